#include "session_io.hpp"

#include <filesystem>
#include <fstream>
#include <iomanip>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::sim::detail {

namespace fs = std::filesystem;

void make_dirs(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) throw core::Error(path, "cannot create folder: " + ec.message());
}

void write_png(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception& e) {
    throw core::Error(path, std::string("cannot write PNG: ") + e.what());
  }
  if (!ok) throw core::Error(path, "cannot write PNG");
}

void save_text(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  if (!f) throw core::Error(path, "cannot open file for writing");
  f << text;
  if (!f) throw core::Error(path, "write failed");
}

void save_yaml(const std::string& path, const YAML::Emitter& out) {
  if (!out.good()) throw core::Error(path, "YAML emitter error: " + out.GetLastError());
  save_text(path, std::string(out.c_str()) + "\n");
}

void emit_vector(YAML::Emitter& out, const Eigen::Vector3d& v) {
  out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
}

void emit_pose(YAML::Emitter& out, const Eigen::Isometry3d& T) {
  const Eigen::Vector4d q = core::quaternion_to_xyzw(Eigen::Quaterniond(T.linear()));
  out << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "translation" << YAML::Value;
  emit_vector(out, T.translation());
  out << YAML::Key << "rotation_quaternion" << YAML::Value << YAML::Flow << YAML::BeginSeq << q[0] << q[1] << q[2]
      << q[3] << YAML::EndSeq;
  out << YAML::EndMap;
}

void emit_extrinsics(YAML::Emitter& out, const std::string& parent, const std::string& child,
                     const Eigen::Isometry3d& T_parent_child) {
  const Eigen::Vector4d q = core::quaternion_to_xyzw(Eigen::Quaterniond(T_parent_child.linear()));
  const Eigen::Matrix4d M = T_parent_child.matrix();
  out << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "parent_frame" << YAML::Value << parent;
  out << YAML::Key << "child_frame" << YAML::Value << child;
  out << YAML::Key << "translation" << YAML::Value;
  emit_vector(out, T_parent_child.translation());
  out << YAML::Key << "rotation_quaternion" << YAML::Value << YAML::Flow << YAML::BeginSeq << q[0] << q[1] << q[2]
      << q[3] << YAML::EndSeq;
  out << YAML::Key << "matrix" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out << M(r, c);
  }
  out << YAML::EndSeq << YAML::EndMap;
}

RigSpec scale_noise(const RigSpec& rig, double scale) {
  RigSpec r = rig;
  r.lidar.range_sigma_m *= scale;
  r.rgb.noise_sigma_dn *= scale;
  r.thermal.netd_k *= scale;
  r.thermal.fpn_pixel_sigma_k *= scale;
  r.thermal.fpn_column_sigma_k *= scale;
  return r;
}

void write_true_calibration(const std::string& dir, const RigSpec& rig, const std::string& what) {
  const fs::path d(dir);
  const fs::path tc = d / "true_calib";
  make_dirs(tc.string());
  core::write_camera_info((d / "rgb.yaml").string(), rig.rgb_intrinsics);
  core::write_camera_info((d / "thermal.yaml").string(), rig.thermal_intrinsics);
  core::write_camera_info((tc / "rgb.yaml").string(), rig.rgb_intrinsics);
  core::write_camera_info((tc / "thermal.yaml").string(), rig.thermal_intrinsics);
  core::Extrinsics e;
  e.child_frame = "lidar";
  e.parent_frame = "rgb";
  e.T_parent_child = rig.T_rgb_lidar;
  core::write_extrinsics((tc / "extrinsics_rgb.yaml").string(), e);
  e.parent_frame = "thermal";
  e.T_parent_child = rig.T_thermal_lidar;
  core::write_extrinsics((tc / "extrinsics_thermal.yaml").string(), e);

  std::ostringstream md;
  md << std::fixed << std::setprecision(6);
  md << "# True calibration (simulated rig)\n\n"
     << "Written by rgbdt_sim for " << what << ". These are the values the simulator used, "
     << "in the layout rgbdt_calibrate writes, so the session can be mapped with its truth "
     << "and any estimate can be compared with them.\n\n"
     << "| camera | tx [m] | ty [m] | tz [m] | roll [deg] | pitch [deg] | yaw [deg] |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const auto& [name, T] : {std::pair<std::string, Eigen::Isometry3d>{"rgb", rig.T_rgb_lidar},
                                {"thermal", rig.T_thermal_lidar}}) {
    const Eigen::Vector3d rpy = core::rotation_to_rpy(T.linear()) * 180.0 / M_PI;
    md << "| " << name << " | " << T.translation().x() << " | " << T.translation().y() << " | "
       << T.translation().z() << " | " << rpy.x() << " | " << rpy.y() << " | " << rpy.z() << " |\n";
  }
  md << "\nT_camera_lidar maps LIDAR points into the camera frame (extrinsics_<camera>.yaml).\n"
     << "LIDAR range noise sigma: " << rig.lidar.range_sigma_m << " m; thermal NETD: " << rig.thermal.netd_k
     << " K; RGB read noise: " << rig.rgb.noise_sigma_dn << " grey levels.\n";
  save_text((tc / "report.md").string(), md.str());
}

void emit_ground_truth_header(YAML::Emitter& out, const RigSpec& rig, const std::string& rig_file) {
  out << YAML::Key << "extrinsics" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "rgb" << YAML::Value;
  emit_extrinsics(out, "rgb", "lidar", rig.T_rgb_lidar);
  out << YAML::Key << "thermal" << YAML::Value;
  emit_extrinsics(out, "thermal", "lidar", rig.T_thermal_lidar);
  out << YAML::EndMap;
  out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "rgb" << YAML::Value
      << "true_calib/rgb.yaml" << YAML::Key << "thermal" << YAML::Value << "true_calib/thermal.yaml" << YAML::EndMap;
  out << YAML::Key << "lidar" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "range_noise_sigma_m" << YAML::Value << rig.lidar.range_sigma_m;
  if (!rig_file.empty()) out << YAML::Key << "rig" << YAML::Value << rig_file;
  out << YAML::EndMap;
}

std::string index_name(int i, int digits) {
  std::ostringstream os;
  os << std::setw(digits) << std::setfill('0') << i;
  return os.str();
}

}  // namespace rgbdt::sim::detail
