#include "rgbdt/core/camera_info.hpp"

#include <fstream>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {
namespace {

// A ROS matrix entry {rows: R, cols: C, data: [R*C finite numbers]} of the given shape.
std::vector<double> matrix_data(const YamlField& root, const std::string& key, int rows, int cols) {
  const std::string shape = std::to_string(rows) + "x" + std::to_string(cols);
  const YamlField m = root.at(key, "{rows: " + std::to_string(rows) + ", cols: " +
                                       std::to_string(cols) + ", data: [...]}");
  m.expect_map("a mapping {rows, cols, data} of a " + shape + " matrix");
  const auto r = m.at("rows", "an integer").as_integer(rows, rows, "rows: " + std::to_string(rows) + " (a " + shape + " matrix)");
  const auto c = m.at("cols", "an integer").as_integer(cols, cols, "cols: " + std::to_string(cols) + " (a " + shape + " matrix)");
  return m.at("data", "a list of " + std::to_string(r * c) + " numbers")
      .as_numbers(static_cast<int>(r * c), "a list of " + std::to_string(r * c) + " numbers");
}

void write_matrix(std::ostream& os, const char* key, int rows, int cols,
                  const std::vector<double>& data) {
  os << key << ":\n  rows: " << rows << "\n  cols: " << cols << "\n  data: [";
  for (size_t i = 0; i < data.size(); ++i) os << (i ? ", " : "") << data[i];
  os << "]\n";
}

// Coefficients each ROS model name takes.
int ros_model_size(const std::string& name) {
  if (name == "plumb_bob") return 5;
  if (name == "rational_polynomial") return 8;
  if (name == "equidistant" || name == "fisheye") return 4;
  if (name == "none") return 0;
  return -1;
}

}  // namespace

static CameraIntrinsics parse_camera_info_node(const YAML::Node& document, const std::string& source) {
  const YamlField root(document, source);
  CameraIntrinsics c;
  const std::string size_range = " in [1, " + std::to_string(kMaxImageSide) + "]";
  c.width = static_cast<int>(root.at("image_width", "an integer")
                                 .as_integer(1, kMaxImageSide, "an integer width in pixels" + size_range));
  c.height = static_cast<int>(root.at("image_height", "an integer")
                                  .as_integer(1, kMaxImageSide, "an integer height in pixels" + size_range));
  if (const auto name = root.find("camera_name")) c.camera_name = name->as_string("a camera name", true);
  const std::vector<double> K = matrix_data(root, "camera_matrix", 3, 3);
  const YamlField k_field = root.at("camera_matrix", "").at("data", "");
  c.fx = K[0];
  c.fy = K[4];
  c.cx = K[2];
  c.cy = K[5];
  if (K[1] != 0.0) k_field.fail("skew " + std::to_string(K[1]) + ", expected 0 (no skew)");
  if (K[3] != 0.0 || K[6] != 0.0 || K[7] != 0.0 || K[8] != 1.0) {
    k_field.fail("expected the form [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  if (!(c.fx > 0.0) || !(c.fy > 0.0)) {
    k_field.fail("fx = " + std::to_string(c.fx) + ", fy = " + std::to_string(c.fy) +
                 ", expected focal lengths > 0 px");
  }
  if (!(c.cx >= 0.0 && c.cx <= c.width) || !(c.cy >= 0.0 && c.cy <= c.height)) {
    std::ostringstream os;
    os << "principal point cx = " << c.cx << ", cy = " << c.cy << ", expected inside the "
       << c.width << "x" << c.height << " image (0 <= cx <= " << c.width << ", 0 <= cy <= "
       << c.height << ")";
    k_field.fail(os.str());
  }
  const auto model_field = root.find("distortion_model");
  const std::string model = model_field ? model_field->as_string("a distortion model name")
                                        : std::string("plumb_bob");
  const int n_model = ros_model_size(model);
  if (n_model < 0) {
    model_field->fail("expected plumb_bob, rational_polynomial (with k4 = k5 = k6 = 0) or equidistant");
  }
  if (const auto d = root.find("distortion_coefficients")) {
    const std::string expected = std::to_string(n_model) + " coefficients for distortion_model " + model;
    d->expect_map("a mapping {rows: 1, cols: N, data: [N numbers]}");
    const auto r = d->at("rows", "an integer").as_integer(0, 1, "rows: 1 (" + expected + ")");
    const auto n = d->at("cols", "an integer").as_integer(0, 64, "cols: N (" + expected + ")");
    const YamlField data = d->at("data", "a list of " + expected);
    if (r * n != static_cast<long long>(data.node().size())) {
      data.fail("expected rows x cols = " + std::to_string(r) + " x " + std::to_string(n) + " numbers");
    }
    c.distortion = data.as_numbers(static_cast<int>(r * n));
    if (static_cast<int>(c.distortion.size()) != n_model) {
      data.fail("expected " + expected + (model == "rational_polynomial"
                                              ? " (k1 k2 p1 p2 k3 k4 k5 k6; supported when k4 = k5 = k6 = 0, as plumb_bob)"
                                              : std::string()));
    }
    if (model == "rational_polynomial" &&
        (c.distortion[5] != 0.0 || c.distortion[6] != 0.0 || c.distortion[7] != 0.0)) {
      data.fail("expected k4 = k5 = k6 = 0 (the rational model is supported only as plumb_bob)");
    }
  }
  c.model = distortion_model_from_string(model == "rational_polynomial" ? "plumb_bob" : model);
  if (model == "rational_polynomial") c.distortion.resize(5);
  c.distortion.resize(static_cast<std::size_t>(distortion_size(c.model)), 0.0);
  if (root.has("rectification_matrix")) matrix_data(root, "rectification_matrix", 3, 3);
  if (root.has("projection_matrix")) matrix_data(root, "projection_matrix", 3, 4);
  const std::string why = c.validate();
  if (!why.empty()) throw Error(source, why);
  return c;
}

CameraIntrinsics parse_camera_info(const std::string& text, const std::string& source) {
  return parse_camera_info_node(load_yaml_string(text, source), source);
}

CameraIntrinsics read_camera_info(const std::string& path) {
  return parse_camera_info_node(load_yaml_file(path), path);
}

std::string format_camera_info(const CameraIntrinsics& c) {
  std::ostringstream os;
  os << std::setprecision(17);
  os << "image_width: " << c.width << "\nimage_height: " << c.height
     << "\ncamera_name: " << c.camera_name << "\n";
  write_matrix(os, "camera_matrix", 3, 3, {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1});
  os << "distortion_model: " << to_string(c.model) << "\n";
  std::vector<double> d = c.distortion;
  d.resize(distortion_size(c.model == DistortionModel::kNone ? DistortionModel::kPlumbBob : c.model), 0.0);
  write_matrix(os, "distortion_coefficients", 1, static_cast<int>(d.size()), d);
  write_matrix(os, "rectification_matrix", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1});
  write_matrix(os, "projection_matrix", 3, 4, {c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0});
  return os.str();
}

void write_camera_info(const std::string& path, const CameraIntrinsics& c) {
  const std::string why = c.validate();
  if (!why.empty()) throw std::invalid_argument("cannot write " + path + ": " + why);
  write_file_atomic(path, format_camera_info(c));
}

}  // namespace rgbdt::core
