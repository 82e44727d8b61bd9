#include <gtest/gtest.h>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/yaml_util.hpp"
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

namespace {
std::string with(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("test text lacks " + from);
  return text.replace(at, from.size(), to);
}
}  // namespace

TEST(CameraInfo, PrincipalPointOutsideTheImageIsRejected) {
  const std::string text = with(kRosYaml, "320.5, 0, 417.9", "99999, 0, 417.9");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "camera_matrix", "99999", "inside the 640x512 image"});
  const std::string cy = with(kRosYaml, "256.25, 0, 0, 1]", "-3, 0, 0, 1]");
  expect_error_mentions<Error>([&] { parse_camera_info(cy, "cam.yaml"); }, {"cam.yaml", "cy = -3"});
}

TEST(CameraInfo, NegativeDistortionRowsAreRejected) {
  const std::string text = with(kRosYaml, "  rows: 1\n  cols: 5", "  rows: -1\n  cols: 5");
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "distortion_coefficients.rows", "'-1'", "rows: 1"});
}

TEST(CameraInfo, DistortionCountMustMatchTheModel) {
  const std::string four = with(with(kRosYaml, "cols: 5", "cols: 4"), "-0.002, 0]", "-0.002]");
  expect_error_mentions<Error>([&] { parse_camera_info(four, "cam.yaml"); },
                               {"cam.yaml", "distortion_coefficients.data", "5 coefficients", "plumb_bob"});
  const std::string rational = with(with(with(kRosYaml, "cols: 5", "cols: 8"), "-0.002, 0]", "-0.002, 0, 0, 0, 0]"),
                                    "plumb_bob", "rational_polynomial");
  const CameraIntrinsics c = parse_camera_info(rational, "cam.yaml");
  EXPECT_EQ(c.model, DistortionModel::kPlumbBob);
  EXPECT_EQ(c.distortion.size(), 5u);
  const std::string k4 = with(rational, "-0.002, 0, 0, 0, 0]", "-0.002, 0, 0.1, 0, 0]");
  expect_error_mentions<Error>([&] { parse_camera_info(k4, "cam.yaml"); }, {"cam.yaml", "k4 = k5 = k6 = 0"});
}

TEST(CameraInfo, NonFiniteAndHexNumbersAreRejected) {
  expect_error_mentions<Error>([&] { parse_camera_info(with(kRosYaml, "-0.31", ".nan"), "cam.yaml"); },
                               {"cam.yaml", "distortion_coefficients.data[0]", "'.nan'", "finite number"});
  expect_error_mentions<Error>([&] { parse_camera_info(with(kRosYaml, "417.9,", ".inf,"), "cam.yaml"); },
                               {"cam.yaml", "camera_matrix.data[4]", "'.inf'"});
  expect_error_mentions<Error>([&] { parse_camera_info(with(kRosYaml, "image_width: 640", "image_width: 0x280"), "cam.yaml"); },
                               {"cam.yaml", "image_width", "'0x280'"});
  expect_error_mentions<Error>([&] { parse_camera_info(with(kRosYaml, "image_width: 640", "image_width: 300000"), "cam.yaml"); },
                               {"cam.yaml", "image_width", "20000"});
}

TEST(CameraInfo, MatrixShapesAreChecked) {
  expect_error_mentions<Error>(
      [&] { parse_camera_info(with(kRosYaml, "  cols: 4\n  data: [417", "  cols: 3\n  data: [417"), "cam.yaml"); },
      {"cam.yaml", "projection_matrix.cols", "3x4"});
  expect_error_mentions<Error>(
      [&] { parse_camera_info(with(kRosYaml, "data: [1, 0, 0, 0, 1, 0, 0, 0, 1]", "data: [1, 0, 0, 0, 1]"), "cam.yaml"); },
      {"cam.yaml", "rectification_matrix.data", "9 numbers"});
}

TEST(CameraInfo, TypeErrorsNameTheKeyPathNotYamlCpp) {
  const std::string text = with(kRosYaml, "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [417.20215, 0, 320.5, 0, 417.9, 256.25, 0, 0, 1]",
                                "camera_matrix: [1, 2, 3]");
  try {
    parse_camera_info(text, "cam.yaml");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("camera_matrix"), std::string::npos) << what;
    EXPECT_NE(what.find("cam.yaml"), std::string::npos) << what;
    EXPECT_EQ(what.find("invalid node"), std::string::npos) << what;
  }
}

TEST(CameraInfo, DuplicateKeysAreRefusedWithTheirLines) {
  const std::string text = std::string(kRosYaml) + "image_width: 1280\n";
  expect_error_mentions<Error>([&] { parse_camera_info(text, "cam.yaml"); },
                               {"cam.yaml", "image_width", "twice", "lines 1 and 21"});
}

TEST(YamlUtil, MissingNodesGiveErrorsNotYamlCppExceptions) {
  const YAML::Node root = load_yaml_string("a: {b: 1}\n", "x.yaml");
  const YAML::Node& const_root = root;
  // Callers in other modules pass children that may not exist.
  expect_error_mentions<Error>([&] { require_double(const_root["missing"], "b", "x.yaml (missing)"); },
                               {"x.yaml (missing)", "b"});
  expect_error_mentions<Error>([&] { YamlField(const_root["missing"], "x.yaml", "missing").as_double(); },
                               {"x.yaml", "missing", "nothing", "finite number"});
}
