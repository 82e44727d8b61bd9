#include <gtest/gtest.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::core;
using rgbdt::test::expect_error_mentions;

namespace {
Extrinsics sample() {
  Extrinsics e;
  e.parent_frame = "rgb";
  e.child_frame = "lidar";
  Vector6d v;
  v << 0.1, -1.4, 0.3, 0.12, -0.05, 0.03;
  e.T_parent_child = from_vector6(v);
  Matrix6d C = Matrix6d::Identity() * 1e-6;
  C(0, 3) = C(3, 0) = 2e-7;
  e.covariance = C;
  return e;
}
}  // namespace

TEST(ExtrinsicsYaml, WriteThenReadRoundTrips) {
  const Extrinsics e = sample();
  const auto path = rgbdt::test::temp_dir("io") / "extrinsics_rgb.yaml";
  write_extrinsics(path.string(), e);
  const Extrinsics r = read_extrinsics(path.string());
  EXPECT_EQ(r.parent_frame, "rgb");
  EXPECT_EQ(r.child_frame, "lidar");
  EXPECT_LT(rotation_error_rad(r.T_parent_child, e.T_parent_child), 1e-12);
  EXPECT_LT(translation_error_m(r.T_parent_child, e.T_parent_child), 1e-15);
  ASSERT_TRUE(r.covariance.has_value());
  EXPECT_TRUE(r.covariance->isApprox(*e.covariance, 1e-15));
}

TEST(ExtrinsicsYaml, MatrixAloneIsEnough) {
  const char* text = R"(parent_frame: camera
child_frame: lidar
matrix: [0, -1, 0, 0.1,  0, 0, -1, 0.2,  1, 0, 0, 0.3,  0, 0, 0, 1]
)";
  const Extrinsics e = parse_extrinsics(text, "e.yaml");
  EXPECT_TRUE((e.T_parent_child * Eigen::Vector3d(1, 0, 0)).isApprox(Eigen::Vector3d(0.1, 0.2, 1.3)));
  EXPECT_FALSE(e.covariance.has_value());
}

TEST(ExtrinsicsYaml, TranslationAndQuaternionAlone) {
  const char* text = R"(parent_frame: camera
child_frame: lidar
translation: [1, 2, 3]
rotation_quaternion: [0, 0, 0, 1]
)";
  const Extrinsics e = parse_extrinsics(text, "e.yaml");
  EXPECT_TRUE(e.T_parent_child.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
}

TEST(ExtrinsicsYaml, InconsistentMatrixIsRejected) {
  const char* text = R"(parent_frame: camera
child_frame: lidar
translation: [1, 2, 3]
rotation_quaternion: [0, 0, 0, 1]
matrix: [1, 0, 0, 1,  0, 1, 0, 2,  0, 0, 1, 3.5,  0, 0, 0, 1]
)";
  expect_error_mentions<Error>([&] { parse_extrinsics(text, "e.yaml"); }, {"e.yaml", "matrix", "disagrees"});
}

TEST(ExtrinsicsYaml, BadQuaternionNamesKey) {
  const char* text = R"(parent_frame: camera
child_frame: lidar
translation: [1, 2, 3]
rotation_quaternion: [1, 0, 0, 1]
)";
  expect_error_mentions<Error>([&] { parse_extrinsics(text, "e.yaml"); },
                               {"e.yaml", "rotation_quaternion", "norm"});
}

TEST(ExtrinsicsYaml, MissingFramesAndPoseAreReported) {
  expect_error_mentions<Error>([] { parse_extrinsics("child_frame: lidar\nmatrix: []\n", "e.yaml"); },
                               {"e.yaml", "parent_frame"});
  expect_error_mentions<Error>([] { parse_extrinsics("parent_frame: c\nchild_frame: l\n", "e.yaml"); },
                               {"e.yaml", "translation", "matrix"});
  expect_error_mentions<Error>(
      [] { parse_extrinsics("parent_frame: c\nchild_frame: l\ntranslation: [1, 2]\nrotation_quaternion: [0,0,0,1]\n", "e.yaml"); },
      {"e.yaml", "translation", "2 values", "3 numbers"});
}

TEST(ExtrinsicsYaml, AsymmetricCovarianceIsRejected) {
  std::string text = "parent_frame: c\nchild_frame: l\ntranslation: [0,0,0]\nrotation_quaternion: [0,0,0,1]\ncovariance: [";
  for (int i = 0; i < 36; ++i) text += (i ? "," : "") + std::to_string(i == 1 ? 1.0 : 0.0);
  text += "]\n";
  expect_error_mentions<Error>([&] { parse_extrinsics(text, "e.yaml"); }, {"e.yaml", "covariance", "symmetric"});
}
