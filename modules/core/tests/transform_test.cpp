#include <gtest/gtest.h>

#include <random>

#include "rgbdt/core/transform.hpp"

using namespace rgbdt::core;

namespace {
Eigen::Isometry3d random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  Vector6d v;
  for (int i = 0; i < 6; ++i) v[i] = u(rng);
  v.head<3>() *= 0.9;  // angle up to ~4.7 rad covers the whole sphere with wrap
  return from_vector6(v);
}
}  // namespace

TEST(Transform, Vector6RoundTripIsExact) {
  std::mt19937 rng(1);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Isometry3d T = random_pose(rng);
    const Eigen::Isometry3d back = from_vector6(to_vector6(T));
    EXPECT_LT(rotation_error_rad(T, back), 1e-9);
    EXPECT_LT(translation_error_m(T, back), 1e-12);
  }
}

// Two rotations 0.004 rad apart across a half turn: to_vector6 puts them on opposite sides
// (vectors about 2 pi apart); to_vector6_near gives the one's rotation vector next to the
// other's, the same rotation, 0.004 rad from it. Elsewhere it is to_vector6 itself.
TEST(Transform, Vector6NearAReferenceStaysInItsChartAcrossAHalfTurn) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0, 1, -1).normalized();
  const Eigen::Isometry3d a = make_transform(Eigen::AngleAxisd(M_PI - 0.002, axis).toRotationMatrix(), {0.1, 0.2, 0.3});
  const Eigen::Isometry3d b = make_transform(Eigen::AngleAxisd(M_PI + 0.002, axis).toRotationMatrix(), {0.1, 0.2, 0.3});
  const Vector6d xa = to_vector6(a);
  EXPECT_GT((to_vector6(b) - xa).head<3>().norm(), 6.0);
  const Vector6d xb = to_vector6_near(b, xa);
  EXPECT_NEAR((xb - xa).head<3>().norm(), 0.004, 1e-9);
  EXPECT_LT(rotation_error_rad(from_vector6(xb), b), 1e-12);
  EXPECT_EQ(xb.tail<3>(), xa.tail<3>());
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Isometry3d T = random_pose(rng);
    if (to_vector6(T).head<3>().norm() > 2.5) continue;  // away from the half turn
    EXPECT_EQ(to_vector6_near(T, to_vector6(T * from_vector6(Vector6d::Constant(0.01)))), to_vector6(T));
  }
}

TEST(Transform, RotationVectorMatchesAngleAxis) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized();
  const Eigen::Matrix3d R = rotation_from_vector(axis * 0.7);
  EXPECT_TRUE(R.isApprox(Eigen::AngleAxisd(0.7, axis).toRotationMatrix(), 1e-12));
  EXPECT_TRUE(rotation_to_vector(R).isApprox(axis * 0.7, 1e-12));
  // Tiny vectors take the first-order branch and stay a rotation to first order.
  const Eigen::Matrix3d small = rotation_from_vector(Eigen::Vector3d(1e-14, 0, 0));
  EXPECT_NEAR(small(2, 1), 1e-14, 1e-20);
}

TEST(Transform, RollPitchYawFollowsRosConvention) {
  const double roll = 0.1, pitch = -0.4, yaw = 2.0;
  const Eigen::Matrix3d R = rotation_from_rpy(roll, pitch, yaw);
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_TRUE(R.isApprox(expected, 1e-12));
  const Eigen::Vector3d rpy = rotation_to_rpy(R);
  EXPECT_NEAR(rpy[0], roll, 1e-12);
  EXPECT_NEAR(rpy[1], pitch, 1e-12);
  EXPECT_NEAR(rpy[2], yaw, 1e-12);
  // Pure yaw of 90 deg turns x into y.
  EXPECT_TRUE((rotation_from_rpy(0, 0, M_PI / 2) * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
}

TEST(Transform, GimbalLockStillReproducesRotation) {
  const Eigen::Matrix3d R = rotation_from_rpy(0.3, M_PI / 2, 0.5);
  const Eigen::Vector3d rpy = rotation_to_rpy(R);
  EXPECT_TRUE(rotation_from_rpy(rpy[0], rpy[1], rpy[2]).isApprox(R, 1e-9));
}

TEST(Transform, QuaternionOrderIsXyzw) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector4d xyzw = quaternion_to_xyzw(q);
  EXPECT_NEAR(xyzw[3], std::cos(0.25), 1e-12);
  EXPECT_NEAR(xyzw[2], std::sin(0.25), 1e-12);
  EXPECT_TRUE(quaternion_from_xyzw(xyzw).isApprox(q, 1e-12));
}

TEST(Transform, RejectsNonUnitQuaternion) {
  EXPECT_THROW(quaternion_from_xyzw({0, 0, 0, 2}), std::invalid_argument);
  EXPECT_THROW(quaternion_from_xyzw({0, 0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(quaternion_from_xyzw({NAN, 0, 0, 1}), std::invalid_argument);
}

TEST(Transform, MatrixRoundTripAndValidation) {
  std::mt19937 rng(2);
  const Eigen::Isometry3d T = random_pose(rng);
  EXPECT_TRUE(transform_from_matrix(T.matrix()).isApprox(T, 1e-12));
  Eigen::Matrix4d bad = T.matrix();
  bad(0, 0) += 0.01;
  EXPECT_THROW(transform_from_matrix(bad), std::invalid_argument);
  Eigen::Matrix4d mirror = Eigen::Matrix4d::Identity();
  mirror(0, 0) = -1;
  EXPECT_THROW(transform_from_matrix(mirror), std::invalid_argument);
  Eigen::Matrix4d last_row = T.matrix();
  last_row(3, 0) = 1;
  EXPECT_THROW(transform_from_matrix(last_row), std::invalid_argument);
}

TEST(Transform, FramesCompose) {
  // T_a_c = T_a_b * T_b_c maps a point in c into a.
  const Eigen::Isometry3d T_a_b = make_transform(rotation_from_rpy(0, 0, M_PI / 2), {1, 0, 0});
  const Eigen::Isometry3d T_b_c = make_transform(Eigen::Matrix3d::Identity(), {0, 2, 0});
  const Eigen::Vector3d p_c(0, 0, 0);
  EXPECT_TRUE(((T_a_b * T_b_c) * p_c).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
}

TEST(Transform, InterpolateEndsAndMiddle) {
  const Eigen::Isometry3d a = make_transform(Eigen::Matrix3d::Identity(), {0, 0, 0});
  const Eigen::Isometry3d b = make_transform(rotation_from_rpy(0, 0, 1.0), {2, 0, 0});
  EXPECT_TRUE(interpolate(a, b, 0).isApprox(a, 1e-12));
  EXPECT_TRUE(interpolate(a, b, 1).isApprox(b, 1e-12));
  const Eigen::Isometry3d m = interpolate(a, b, 0.5);
  EXPECT_NEAR(rotation_to_rpy(m.linear())[2], 0.5, 1e-12);
  EXPECT_NEAR(m.translation().x(), 1.0, 1e-12);
}
