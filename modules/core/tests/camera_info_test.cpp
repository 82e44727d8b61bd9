#include <gtest/gtest.h>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::core;
using rgbdt::test::expect_error_mentions;

namespace {
// As written by ROS camera_calibration (the layout, not a copy of any file).
const char* kRosYaml = R"(image_width: 640
image_height: 512
camera_name: tau2
camera_matrix:
  rows: 3
  cols: 3
  data: [417.20215, 0, 320.5, 0, 417.9, 256.25, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.31, 0.11, 0.001, -0.002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [417.20215, 0, 320.5, 0, 0, 417.9, 256.25, 0, 0, 0, 1, 0]
)";
}  // namespace

TEST(CameraInfo, ParsesRosCalibrationFile) {
  const CameraIntrinsics c = parse_camera_info(kRosYaml, "tau2.yaml");
  EXPECT_EQ(c.camera_name, "tau2");
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 512);
  EXPECT_DOUBLE_EQ(c.fx, 417.20215);
  EXPECT_DOUBLE_EQ(c.fy, 417.9);
  EXPECT_DOUBLE_EQ(c.cx, 320.5);
  EXPECT_DOUBLE_EQ(c.cy, 256.25);
  EXPECT_EQ(c.model, DistortionModel::kPlumbBob);
  ASSERT_EQ(c.distortion.size(), 5u);
  EXPECT_DOUBLE_EQ(c.distortion[0], -0.31);
}

TEST(CameraInfo, WriteThenReadRoundTripsExactly) {
  for (auto model : {DistortionModel::kPlumbBob, DistortionModel::kEquidistant}) {
    CameraIntrinsics c;
    c.camera_name = "rgb";
    c.width = 1288;
    c.height = 964;
    c.fx = 1335.0541234567891;
    c.fy = 1334.1;
    c.cx = 643.123456789;
    c.cy = 480.987654321;
    c.model = model;
    c.distortion = model == DistortionModel::kPlumbBob
                       ? std::vector<double>{-0.2, 0.1, 1e-4, -2e-4, 0.01}
                       : std::vector<double>{0.01, -0.002, 3e-4, -1e-5};
    const auto path = rgbdt::test::temp_dir("io") / "camera.yaml";
    write_camera_info(path.string(), c);
    const CameraIntrinsics r = read_camera_info(path.string());
    EXPECT_EQ(r.camera_name, c.camera_name);
    EXPECT_EQ(r.width, c.width);
    EXPECT_EQ(r.height, c.height);
    EXPECT_EQ(r.fx, c.fx);
    EXPECT_EQ(r.fy, c.fy);
    EXPECT_EQ(r.cx, c.cx);
    EXPECT_EQ(r.cy, c.cy);
    EXPECT_EQ(r.model, c.model);
    EXPECT_EQ(r.distortion, c.distortion);
  }
}

TEST(CameraInfo, MissingFileNamesThePath) {
  expect_error_mentions<Error>([] { read_camera_info("/nonexistent/cam.yaml"); },
                               {"/nonexistent/cam.yaml", "cannot open"});
}

TEST(CameraInfo, MissingKeyNamesFileKeyAndExpectation) {
  std::string text = kRosYaml;
  text.replace(text.find("image_width: 640\n"), 17, "");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "image_width", "integer"});
}

TEST(CameraInfo, WrongTypeNamesValue) {
  std::string text = kRosYaml;
  text.replace(text.find("image_height: 512"), 17, "image_height: tall");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "image_height", "'tall'", "integer"});
}

TEST(CameraInfo, WrongMatrixSizeIsReported) {
  std::string text = kRosYaml;
  text.replace(text.find("data: [417.20215, 0, 320.5, 0, 417.9, 256.25, 0, 0, 1]"), 54,
               "data: [417.20215, 0, 320.5, 0, 417.9, 256.25]");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "data", "6 values", "9 numbers"});
}

TEST(CameraInfo, UnknownDistortionModelIsReported) {
  std::string text = kRosYaml;
  text.replace(text.find("plumb_bob"), 9, "rational_polynomial");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "distortion_model", "rational_polynomial", "plumb_bob"});
}

TEST(CameraInfo, NegativeFocalLengthIsRejected) {
  std::string text = kRosYaml;
  text.replace(text.find("data: [417.20215"), 16, "data: [-417.2021");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); }, {"cam.yaml", "fx"});
}

TEST(CameraInfo, NotYamlReportsLine) {
  expect_error_mentions<Error>([] { parse_camera_info("image_width: [1,\n  2\n  ]]]", "x.yaml"); },
                               {"x.yaml", "line"});
}
