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

namespace {
std::string pose_yaml(const std::string& parent, const std::string& child, const std::string& t,
                      const std::string& q, const std::string& extra = "") {
  return "parent_frame: " + parent + "\nchild_frame: " + child + "\ntranslation: " + t +
         "\nrotation_quaternion: " + q + "\n" + extra;
}
}  // namespace

TEST(ExtrinsicsYaml, LidarParentIsReadAsCameraFromLidar) {
  // A correct T_lidar_rgb: the rgb origin sits 0.2 m along the LIDAR's x axis, turned 90 deg
  // about z. Read as T_rgb_lidar it must map the LIDAR point (0.2, 0, 0) to the rgb origin.
  Extrinsics lidar_rgb;
  lidar_rgb.parent_frame = "lidar";
  lidar_rgb.child_frame = "rgb";
  lidar_rgb.T_parent_child = make_transform(rotation_from_rpy(0, 0, M_PI / 2), {0.2, 0, 0});
  lidar_rgb.covariance = sample().covariance;
  const std::string text = format_extrinsics(lidar_rgb);
  for (const Extrinsics& e : {parse_extrinsics(text, "e.yaml"), parse_extrinsics(text, "e.yaml", {"rgb"})}) {
    EXPECT_EQ(e.parent_frame, "rgb");
    EXPECT_EQ(e.child_frame, "lidar");
    EXPECT_LT((e.T_parent_child * Eigen::Vector3d(0.2, 0, 0)).norm(), 1e-12);
    EXPECT_LT((e.T_parent_child * Eigen::Vector3d(0.2, 1, 0) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);
    ASSERT_TRUE(e.covariance.has_value());
    // Inverting back gives the file's covariance again.
    EXPECT_TRUE(inverted(e).covariance->isApprox(*lidar_rgb.covariance, 1e-6));
  }
  // Our own files (camera parent) read back as written.
  const Extrinsics own = sample();
  const Extrinsics r = parse_extrinsics(format_extrinsics(own), "e.yaml", {"rgb"});
  EXPECT_EQ(r.parent_frame, "rgb");
  EXPECT_LT(rotation_error_rad(r.T_parent_child, own.T_parent_child), 1e-12);
}

TEST(ExtrinsicsYaml, FramesMustBeTheLidarAndTheExpectedCamera) {
  const std::string q = "[0, 0, 0, 1]";
  expect_error_mentions<Error>([&] { parse_extrinsics(pose_yaml("thermal", "lidar", "[0, 0, 0]", q), "e.yaml", {"rgb"}); },
                               {"e.yaml", "parent_frame 'thermal'", "child_frame 'lidar'", "the camera 'rgb'"});
  expect_error_mentions<Error>([&] { parse_extrinsics(pose_yaml("foo", "bar", "[0, 0, 0]", q), "e.yaml", {}); },
                               {"e.yaml", "'foo'", "'bar'", "LIDAR frame"});
  expect_error_mentions<Error>([&] { parse_extrinsics(pose_yaml("lidar", "laser", "[0, 0, 0]", q), "e.yaml", {}); },
                               {"e.yaml", "'lidar'", "'laser'"});
  // With the camera known, the other frame is the LIDAR whatever its name, in either order.
  EXPECT_EQ(parse_extrinsics(pose_yaml("rgb", "livox_frame", "[0.1, 0, 0]", q), "e.yaml", {"rgb"}).child_frame,
            "livox_frame");
  const Extrinsics swapped = parse_extrinsics(pose_yaml("os_sensor", "rgb", "[0.1, 0, 0]", q), "e.yaml", {"rgb"});
  EXPECT_EQ(swapped.parent_frame, "rgb");
  EXPECT_NEAR(swapped.T_parent_child.translation().x(), -0.1, 1e-12);
  // A camera-to-camera file is still readable without expectations.
  EXPECT_EQ(parse_extrinsics(pose_yaml("thermal", "rgb", "[0, 0, 0]", q), "e.yaml").parent_frame, "thermal");
}

TEST(ExtrinsicsYaml, NonFiniteNumbersAreRejected) {
  expect_error_mentions<Error>([] { parse_extrinsics(pose_yaml("rgb", "lidar", "[.nan, 0, 0]", "[0, 0, 0, 1]"), "e.yaml"); },
                               {"e.yaml", "translation[0]", "'.nan'", "finite number"});
  expect_error_mentions<Error>([] { parse_extrinsics(pose_yaml("rgb", "lidar", "[0, 0, 0]", "[0, 0, .inf, 1]"), "e.yaml"); },
                               {"e.yaml", "rotation_quaternion[2]", "'.inf'"});
  std::string m = "parent_frame: rgb\nchild_frame: lidar\nmatrix: [1, 0, 0, nan, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n";
  expect_error_mentions<Error>([&] { parse_extrinsics(m, "e.yaml"); }, {"e.yaml", "matrix[3]", "'nan'"});
}

TEST(ExtrinsicsYaml, QuaternionMustHaveUnitNorm) {
  expect_error_mentions<Error>([] { parse_extrinsics(pose_yaml("rgb", "lidar", "[0, 0, 0]", "[0, 0, 0, 2]"), "e.yaml"); },
                               {"e.yaml", "rotation_quaternion", "norm 2", "unit quaternion"});
  expect_error_mentions<Error>([] { parse_extrinsics(pose_yaml("rgb", "lidar", "[0, 0, 0]", "[0, 0, 0, 0]"), "e.yaml"); },
                               {"e.yaml", "rotation_quaternion", "norm 0"});
}

TEST(ExtrinsicsYaml, CovarianceMustBeFiniteAndPositiveSemiDefinite) {
  std::string negative = "[";
  for (int i = 0; i < 36; ++i) negative += (i ? "," : "") + std::string(i == 0 ? "-1" : (i % 7 == 0 ? "1" : "0"));
  negative += "]";
  expect_error_mentions<Error>(
      [&] { parse_extrinsics(pose_yaml("rgb", "lidar", "[0, 0, 0]", "[0, 0, 0, 1]", "covariance: " + negative + "\n"), "e.yaml"); },
      {"e.yaml", "covariance", "positive semi-definite"});
  std::string nan = negative;
  nan.replace(1, 2, ".nan");
  expect_error_mentions<Error>(
      [&] { parse_extrinsics(pose_yaml("rgb", "lidar", "[0, 0, 0]", "[0, 0, 0, 1]", "covariance: " + nan + "\n"), "e.yaml"); },
      {"e.yaml", "covariance[0]", "finite"});
}

TEST(ExtrinsicsYaml, WriteIntoAMissingFolderNamesThePath) {
  expect_error_mentions<Error>([] { write_extrinsics("/nonexistent/dir/e.yaml", sample()); },
                               {"/nonexistent/dir/e.yaml"});
}
