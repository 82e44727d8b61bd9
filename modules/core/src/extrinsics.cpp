#include "rgbdt/core/extrinsics.hpp"

#include <fstream>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {

Extrinsics parse_extrinsics(const std::string& text, const std::string& source) {
  const YAML::Node root = load_yaml_string(text, source);
  Extrinsics e;
  e.parent_frame = require_string(root, "parent_frame", source);
  e.child_frame = require_string(root, "child_frame", source);
  const bool has_tq = root["translation"] || root["rotation_quaternion"];
  const bool has_matrix = static_cast<bool>(root["matrix"]);
  if (!has_tq && !has_matrix) {
    throw Error(source,
                "missing key 'translation' + 'rotation_quaternion' or 'matrix' (expected at least one)");
  }
  std::optional<Eigen::Isometry3d> from_tq, from_matrix;
  if (has_tq) {
    const auto t = require_numbers(root, "translation", source, 3);
    const auto q = require_numbers(root, "rotation_quaternion", source, 4);
    try {
      const Eigen::Quaterniond quat = quaternion_from_xyzw({q[0], q[1], q[2], q[3]});
      from_tq = make_transform(quat.toRotationMatrix(), {t[0], t[1], t[2]});
    } catch (const std::invalid_argument& ex) {
      throw Error(source, std::string("key 'rotation_quaternion': ") + ex.what());
    }
  }
  if (has_matrix) {
    const auto m = require_numbers(root, "matrix", source, 16);
    Eigen::Matrix4d M;
    for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = m[i];
    try {
      from_matrix = transform_from_matrix(M);
    } catch (const std::invalid_argument& ex) {
      throw Error(source, std::string("key 'matrix': ") + ex.what());
    }
  }
  if (from_tq && from_matrix) {
    const double dr = rotation_error_rad(*from_tq, *from_matrix);
    const double dt = translation_error_m(*from_tq, *from_matrix);
    if (dr > 1e-6 || dt > 1e-6) {
      std::ostringstream os;
      os << "'matrix' disagrees with 'translation'/'rotation_quaternion' by " << dr << " rad and "
         << dt << " m (expected the same transform)";
      throw Error(source, os.str());
    }
  }
  e.T_parent_child = from_tq ? *from_tq : *from_matrix;
  if (root["covariance"]) {
    const auto c = require_numbers(root, "covariance", source, 36);
    Matrix6d C;
    for (int i = 0; i < 36; ++i) C(i / 6, i % 6) = c[i];
    if ((C - C.transpose()).norm() > 1e-9 * std::max(1.0, C.norm())) {
      throw Error(source, "key 'covariance' is not symmetric (expected a 6x6 covariance)");
    }
    e.covariance = C;
  }
  return e;
}

Extrinsics read_extrinsics(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path, "cannot open extrinsics file for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_extrinsics(ss.str(), path);
}

std::string format_extrinsics(const Extrinsics& e) {
  std::ostringstream os;
  os << std::setprecision(17);
  const Eigen::Vector3d t = e.T_parent_child.translation();
  const Eigen::Vector4d q = quaternion_to_xyzw(Eigen::Quaterniond(e.T_parent_child.linear()));
  os << "# T_" << e.parent_frame << "_" << e.child_frame << ": maps points from '" << e.child_frame
     << "' into '" << e.parent_frame << "'\n";
  os << "parent_frame: " << e.parent_frame << "\nchild_frame: " << e.child_frame << "\n";
  os << "translation: [" << t.x() << ", " << t.y() << ", " << t.z() << "]\n";
  os << "rotation_quaternion: [" << q[0] << ", " << q[1] << ", " << q[2] << ", " << q[3] << "]\n";
  const Eigen::Matrix4d M = e.T_parent_child.matrix();
  os << "matrix: [";
  for (int i = 0; i < 16; ++i) os << (i ? ", " : "") << M(i / 4, i % 4);
  os << "]\n";
  if (e.covariance) {
    os << "# covariance order: rx ry rz [rad] tx ty tz [m]\ncovariance: [";
    for (int i = 0; i < 36; ++i) os << (i ? ", " : "") << (*e.covariance)(i / 6, i % 6);
    os << "]\n";
  }
  return os.str();
}

void write_extrinsics(const std::string& path, const Extrinsics& e) {
  std::ofstream out(path);
  if (!out) throw Error(path, "cannot open file for writing");
  out << format_extrinsics(e);
  if (!out) throw Error(path, "write failed");
}

}  // namespace rgbdt::core
