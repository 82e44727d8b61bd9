#include "rgbdt/core/transform.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace rgbdt::core {

Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& rv) {
  const double angle = rv.norm();
  if (angle < 1e-12) {
    // First order: R = I + [rv]x keeps the map smooth at the origin.
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    R(0, 1) = -rv.z(); R(0, 2) = rv.y();
    R(1, 0) = rv.z();  R(1, 2) = -rv.x();
    R(2, 0) = -rv.y(); R(2, 1) = rv.x();
    return R;
  }
  return Eigen::AngleAxisd(angle, rv / angle).toRotationMatrix();
}

Eigen::Vector3d rotation_to_vector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

Eigen::Isometry3d from_vector6(const Vector6d& v) {
  return make_transform(rotation_from_vector(v.head<3>()), v.tail<3>());
}

Vector6d to_vector6(const Eigen::Isometry3d& T) {
  Vector6d v;
  v.head<3>() = rotation_to_vector(T.linear());
  v.tail<3>() = T.translation();
  return v;
}

Vector6d to_vector6_near(const Eigen::Isometry3d& T, const Vector6d& reference) {
  Vector6d v = to_vector6(T);
  const double angle = v.head<3>().norm();
  if (angle < 1e-12) return v;
  const Eigen::Vector3d turn = v.head<3>() * (2.0 * M_PI / angle);
  Eigen::Vector3d best = v.head<3>();
  for (const Eigen::Vector3d& candidate : {Eigen::Vector3d(v.head<3>() - turn), Eigen::Vector3d(v.head<3>() + turn)}) {
    if ((candidate - reference.head<3>()).norm() < (best - reference.head<3>()).norm()) best = candidate;
  }
  v.head<3>() = best;
  return v;
}

Eigen::Matrix3d rotation_from_rpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d rotation_to_rpy(const Eigen::Matrix3d& R) {
  // R = Rz(yaw) Ry(pitch) Rx(roll): R(2,0) = -sin(pitch).
  // atan2 keeps full precision near +-90 deg, where asin loses half the digits.
  const double pitch = std::atan2(-R(2, 0), std::hypot(R(2, 1), R(2, 2)));
  double roll, yaw;
  if (std::hypot(R(2, 1), R(2, 2)) > 1e-6) {
    roll = std::atan2(R(2, 1), R(2, 2));
    yaw = std::atan2(R(1, 0), R(0, 0));
  } else {  // gimbal lock: only roll - yaw (or roll + yaw) is defined; put it all in yaw
    roll = 0.0;
    yaw = std::atan2(-R(0, 1), R(1, 1));
  }
  return {roll, pitch, yaw};
}

Eigen::Quaterniond quaternion_from_xyzw(const Eigen::Vector4d& xyzw) {
  const double n = xyzw.norm();
  if (!std::isfinite(n) || std::abs(n - 1.0) > 1e-3) {
    std::ostringstream os;
    os << "quaternion [x y z w] = [" << xyzw.transpose() << "] has norm " << n
       << ", expected 1 (is the order x y z w?)";
    throw std::invalid_argument(os.str());
  }
  Eigen::Quaterniond q(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
  q.normalize();
  return q;
}

Eigen::Vector4d quaternion_to_xyzw(const Eigen::Quaterniond& q) {
  return {q.x(), q.y(), q.z(), q.w()};
}

Eigen::Isometry3d make_transform(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

Eigen::Isometry3d transform_from_matrix(const Eigen::Matrix4d& M) {
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double ortho = (R * R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!M.allFinite() || ortho > 1e-6 || R.determinant() < 0) {
    std::ostringstream os;
    os << "4x4 matrix is not a rigid transform: rotation part deviates from orthonormal by "
       << ortho << " (expected < 1e-6 and determinant +1)";
    throw std::invalid_argument(os.str());
  }
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    throw std::invalid_argument("4x4 matrix last row is not [0 0 0 1]");
  }
  // Re-orthonormalise so that accumulated rounding does not leak into solvers.
  const Eigen::Quaterniond q(R);
  return make_transform(q.normalized().toRotationMatrix(), M.topRightCorner<3, 1>());
}

double rotation_error_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

double translation_error_m(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s) {
  const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
  return make_transform(qa.slerp(s, qb).toRotationMatrix(),
                        (1.0 - s) * a.translation() + s * b.translation());
}

}  // namespace rgbdt::core
