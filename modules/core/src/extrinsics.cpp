#include "rgbdt/core/extrinsics.hpp"

#include <Eigen/Eigenvalues>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {

namespace {

std::string lower_frame(const std::string& frame) {
  std::string f;
  for (const char ch : frame) f += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  for (const char* suffix : {"_link", "_frame"}) {
    const std::string s(suffix);
    if (f.size() > s.size() && f.compare(f.size() - s.size(), s.size(), s) == 0) {
      f.resize(f.size() - s.size());
    }
  }
  return f;
}

std::string list_names(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// The file as written: T_parent_child and the frames, every value checked.
Extrinsics parse_literal(const YAML::Node& document, const std::string& source) {
  const YamlField root(document, source);
  Extrinsics e;
  e.parent_frame = root.at("parent_frame", "a frame name").as_string("a frame name");
  e.child_frame = root.at("child_frame", "a frame name").as_string("a frame name");
  const bool has_tq = root.has("translation") || root.has("rotation_quaternion");
  const bool has_matrix = root.has("matrix");
  if (!has_tq && !has_matrix) {
    throw Error(source,
                "missing key 'translation' + 'rotation_quaternion' or 'matrix' (expected at least one)");
  }
  std::optional<Eigen::Isometry3d> from_tq, from_matrix;
  if (has_tq) {
    const auto t = root.at("translation", "[x, y, z] in metres").as_numbers(3, "a list of 3 numbers [x, y, z] in metres");
    const YamlField qf = root.at("rotation_quaternion", "[x, y, z, w]");
    const auto q = qf.as_numbers(4, "a list of 4 numbers [x, y, z, w]");
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(std::abs(norm - 1.0) < 1e-3)) {
      std::ostringstream os;
      os << "norm " << norm << ", expected a unit quaternion [x, y, z, w] (norm within 1e-3 of 1)";
      qf.fail(os.str());
    }
    const Eigen::Quaterniond quat = quaternion_from_xyzw({q[0], q[1], q[2], q[3]});
    from_tq = make_transform(quat.toRotationMatrix(), {t[0], t[1], t[2]});
  }
  if (has_matrix) {
    const YamlField mf = root.at("matrix", "16 numbers, row major");
    const auto m = mf.as_numbers(16, "a list of 16 numbers (4x4, row major)");
    Eigen::Matrix4d M;
    for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = m[i];
    try {
      from_matrix = transform_from_matrix(M);
    } catch (const std::invalid_argument& ex) {
      mf.fail(std::string("expected a rigid transform (") + ex.what() + ")");
    }
  }
  if (from_tq && from_matrix) {
    const double dr = rotation_error_rad(*from_tq, *from_matrix);
    const double dt = translation_error_m(*from_tq, *from_matrix);
    if (!(dr <= 1e-6) || !(dt <= 1e-6)) {
      std::ostringstream os;
      os << "'matrix' disagrees with 'translation'/'rotation_quaternion' by " << dr << " rad and "
         << dt << " m (expected the same transform)";
      throw Error(source, os.str());
    }
  }
  e.T_parent_child = from_tq ? *from_tq : *from_matrix;
  if (const auto cf = root.find("covariance")) {
    const auto c = cf->as_numbers(36, "a list of 36 numbers (6x6, row major)");
    Matrix6d C;
    for (int i = 0; i < 36; ++i) C(i / 6, i % 6) = c[i];
    const double scale = std::max(1e-300, C.cwiseAbs().maxCoeff());
    if ((C - C.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
      cf->fail("expected a symmetric 6x6 covariance");
    }
    const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(0.5 * (C + C.transpose()));
    if (eig.eigenvalues().minCoeff() < -1e-9 * scale) {
      std::ostringstream os;
      os << "smallest eigenvalue " << eig.eigenvalues().minCoeff()
         << ", expected a positive semi-definite covariance";
      cf->fail(os.str());
    }
    e.covariance = C;
  }
  return e;
}

Extrinsics with_camera_parent(Extrinsics e, const ExtrinsicsFrames& frames) {
  if (is_lidar_frame(e.parent_frame, frames) && !is_lidar_frame(e.child_frame, frames)) {
    return inverted(e);
  }
  return e;
}

Extrinsics camera_lidar(const Extrinsics& literal, const std::string& source,
                        const ExtrinsicsFrames& frames) {
  // When the camera is known, its name decides the direction whatever the LIDAR's frame is
  // called (livox_frame, os_sensor, ...): the other frame is the LIDAR.
  if (!frames.camera.empty() && literal.parent_frame != literal.child_frame) {
    if (literal.parent_frame == frames.camera && !is_lidar_frame(literal.parent_frame, frames)) return literal;
    if (literal.child_frame == frames.camera && !is_lidar_frame(literal.child_frame, frames)) return inverted(literal);
  }
  const Extrinsics e = with_camera_parent(literal, frames);
  const bool lidar_child = is_lidar_frame(e.child_frame, frames);
  const bool camera_parent = !is_lidar_frame(e.parent_frame, frames) &&
                             (frames.camera.empty() || e.parent_frame == frames.camera);
  if (!lidar_child || !camera_parent) {
    throw Error(source, "frames parent_frame '" + literal.parent_frame + "', child_frame '" +
                            literal.child_frame + "', expected one LIDAR frame (" +
                            list_names(frames.lidar) + ") and " +
                            (frames.camera.empty() ? std::string("one camera frame")
                                                   : "the camera '" + frames.camera + "'"));
  }
  return e;
}

}  // namespace

bool is_lidar_frame(const std::string& frame, const ExtrinsicsFrames& frames) {
  const std::string f = lower_frame(frame);
  for (const auto& name : frames.lidar) {
    if (f == lower_frame(name)) return true;
  }
  return false;
}

Extrinsics inverted(const Extrinsics& e) {
  Extrinsics out;
  out.parent_frame = e.child_frame;
  out.child_frame = e.parent_frame;
  out.T_parent_child = e.T_parent_child.inverse();
  if (e.covariance) {
    // J = d to_vector6(from_vector6(v)^-1) / dv at v = to_vector6(T), by central differences.
    const Vector6d v = to_vector6(e.T_parent_child);
    Matrix6d J;
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Vector6d dv = Vector6d::Zero();
      dv[k] = h;
      J.col(k) = (to_vector6(from_vector6(v + dv).inverse()) - to_vector6(from_vector6(v - dv).inverse())) /
                 (2 * h);
    }
    out.covariance = J * *e.covariance * J.transpose();
  }
  return out;
}

Extrinsics parse_extrinsics(const std::string& text, const std::string& source) {
  return with_camera_parent(parse_literal(load_yaml_string(text, source), source), ExtrinsicsFrames{});
}

Extrinsics read_extrinsics(const std::string& path) {
  return with_camera_parent(parse_literal(load_yaml_file(path), path), ExtrinsicsFrames{});
}

Extrinsics parse_extrinsics(const std::string& text, const std::string& source,
                            const ExtrinsicsFrames& frames) {
  return camera_lidar(parse_literal(load_yaml_string(text, source), source), source, frames);
}

Extrinsics read_extrinsics(const std::string& path, const ExtrinsicsFrames& frames) {
  return camera_lidar(parse_literal(load_yaml_file(path), path), path, frames);
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
  write_file_atomic(path, format_extrinsics(e));
}

}  // namespace rgbdt::core
