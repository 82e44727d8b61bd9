#pragma once
/// \file
/// Rigid transforms with explicit frames.
///
/// Naming: T_a_b is an Eigen::Isometry3d that maps points expressed in frame b into
/// frame a (p_a = T_a_b * p_b). So T_camera_lidar takes LIDAR points into the camera.
///
/// The solvers use a 6-vector [rx ry rz tx ty tz]: a rotation vector (axis * angle,
/// radians) followed by a translation (metres). This order is also the order of every
/// 6x6 covariance in rgbdt.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rgbdt::core {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// [rx ry rz tx ty tz] -> transform. Rotation vector of any length (exact, not small-angle).
Eigen::Isometry3d from_vector6(const Vector6d& v);
/// transform -> [rx ry rz tx ty tz], with the rotation angle in [0, pi].
Vector6d to_vector6(const Eigen::Isometry3d& T);
/// to_vector6(T) with the rotation vector, among those of the same rotation (its axis times
/// angle + 2 pi k), the one nearest `reference`'s. Near a half turn two rotation vectors of
/// length about pi on opposite sides stand for nearby rotations; a difference of vectors,
/// or a covariance of them, means something only with both in one chart.
Vector6d to_vector6_near(const Eigen::Isometry3d& T, const Vector6d& reference);

/// Rotation vector (axis * angle [rad]) <-> rotation matrix.
Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& rotation_vector);
Eigen::Vector3d rotation_to_vector(const Eigen::Matrix3d& R);

/// Roll-pitch-yaw [rad], applied as R = Rz(yaw) * Ry(pitch) * Rx(roll) (ROS convention).
Eigen::Matrix3d rotation_from_rpy(double roll, double pitch, double yaw);
/// Inverse of rotation_from_rpy; pitch in [-pi/2, pi/2].
Eigen::Vector3d rotation_to_rpy(const Eigen::Matrix3d& R);

/// Quaternion given as [x y z w] (ROS order). Throws std::invalid_argument if its norm is
/// not within 1e-3 of 1 (a sign that the order or the values are wrong).
Eigen::Quaterniond quaternion_from_xyzw(const Eigen::Vector4d& xyzw);
Eigen::Vector4d quaternion_to_xyzw(const Eigen::Quaterniond& q);

/// Builds a transform from rotation and translation.
Eigen::Isometry3d make_transform(const Eigen::Matrix3d& R, const Eigen::Vector3d& t);
/// 4x4 homogeneous matrix -> transform; throws std::invalid_argument if the matrix is not
/// a rigid transform (rotation not orthonormal within 1e-6, or last row not [0 0 0 1]).
Eigen::Isometry3d transform_from_matrix(const Eigen::Matrix4d& M);

/// Angle of the rotation between two transforms [rad] and distance of their translations [m].
double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);
double translation_error_m(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

/// Interpolates between two poses: slerp on rotation, linear on translation, s in [0, 1].
Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s);

}  // namespace rgbdt::core
