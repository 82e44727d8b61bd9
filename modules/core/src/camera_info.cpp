#include "rgbdt/core/camera_info.hpp"

#include <fstream>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {
namespace {

std::vector<double> matrix_data(const YAML::Node& root, const std::string& key, int rows, int cols,
                                const std::string& source) {
  const YAML::Node m = require_key(root, key, source,
                                   "{rows: " + std::to_string(rows) + ", cols: " +
                                       std::to_string(cols) + ", data: [...]}");
  if (!m.IsMap()) throw Error(source, "key '" + key + "' must be a mapping with rows, cols, data");
  const int r = require_int(m, "rows", source + " (" + key + ")");
  const int c = require_int(m, "cols", source + " (" + key + ")");
  if (rows >= 0 && (r != rows || c != cols)) {
    std::ostringstream os;
    os << "key '" << key << "' is " << r << "x" << c << ", expected " << rows << "x" << cols;
    throw Error(source, os.str());
  }
  return require_numbers(m, "data", source + " (" + key + ")", r * c);
}

void write_matrix(std::ostream& os, const char* key, int rows, int cols,
                  const std::vector<double>& data) {
  os << key << ":\n  rows: " << rows << "\n  cols: " << cols << "\n  data: [";
  for (size_t i = 0; i < data.size(); ++i) os << (i ? ", " : "") << data[i];
  os << "]\n";
}

}  // namespace

CameraIntrinsics parse_camera_info(const std::string& text, const std::string& source) {
  const YAML::Node root = load_yaml_string(text, source);
  CameraIntrinsics c;
  c.width = require_int(root, "image_width", source);
  c.height = require_int(root, "image_height", source);
  if (root["camera_name"]) c.camera_name = require_string(root, "camera_name", source);
  const std::vector<double> K = matrix_data(root, "camera_matrix", 3, 3, source);
  c.fx = K[0];
  c.fy = K[4];
  c.cx = K[2];
  c.cy = K[5];
  if (K[1] != 0.0) {
    throw Error(source, "camera_matrix has skew " + std::to_string(K[1]) + ", expected 0");
  }
  if (K[3] != 0.0 || K[6] != 0.0 || K[7] != 0.0 || K[8] != 1.0) {
    throw Error(source, "camera_matrix is not of the form [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  const std::string model = root["distortion_model"]
                                ? require_string(root, "distortion_model", source)
                                : std::string("plumb_bob");
  try {
    c.model = distortion_model_from_string(model);
  } catch (const std::invalid_argument& e) {
    throw Error(source, std::string("key 'distortion_model': ") + e.what());
  }
  if (root["distortion_coefficients"]) {
    const YAML::Node d = root["distortion_coefficients"];
    const int r = require_int(d, "rows", source + " (distortion_coefficients)");
    const int n = require_int(d, "cols", source + " (distortion_coefficients)");
    c.distortion = require_numbers(d, "data", source + " (distortion_coefficients)", r * n);
  }
  const int expected = distortion_size(c.model);
  if (c.model == DistortionModel::kEquidistant && static_cast<int>(c.distortion.size()) != expected) {
    throw Error(source, "distortion_coefficients has " + std::to_string(c.distortion.size()) +
                            " values, expected 4 (k1 k2 k3 k4) for equidistant");
  }
  if (c.model == DistortionModel::kPlumbBob && !c.distortion.empty() && c.distortion.size() < 4) {
    throw Error(source, "distortion_coefficients has " + std::to_string(c.distortion.size()) +
                            " values, expected 5 (k1 k2 p1 p2 k3) for plumb_bob");
  }
  c.distortion.resize(std::max<size_t>(c.distortion.size(), expected), 0.0);
  const std::string why = c.validate();
  if (!why.empty()) throw Error(source, why);
  return c;
}

CameraIntrinsics read_camera_info(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path, "cannot open camera_info file for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_camera_info(ss.str(), path);
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
  std::ofstream out(path);
  if (!out) throw Error(path, "cannot open file for writing");
  out << format_camera_info(c);
  if (!out) throw Error(path, "write failed");
}

}  // namespace rgbdt::core
