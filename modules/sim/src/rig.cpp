#include "rgbdt/sim/rig.hpp"

#include <sstream>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::sim {

namespace {
constexpr double kDeg = M_PI / 180.0;
}

core::CameraIntrinsics default_rgb_intrinsics() {
  core::CameraIntrinsics k;
  k.camera_name = "rgb";
  k.width = 1288;
  k.height = 964;
  k.fx = 1335.2;
  k.fy = 1336.1;
  k.cx = 641.7;
  k.cy = 485.3;
  k.model = core::DistortionModel::kPlumbBob;
  k.distortion = {-0.112, 0.081, 0.0004, -0.0003, 0.0};
  return k;
}

core::CameraIntrinsics default_thermal_intrinsics() {
  core::CameraIntrinsics k;
  k.camera_name = "thermal";
  k.width = 640;
  k.height = 512;
  k.fx = 417.3;
  k.fy = 417.9;
  k.cx = 322.4;
  k.cy = 253.1;
  k.model = core::DistortionModel::kPlumbBob;
  k.distortion = {-0.243, 0.096, -0.0006, 0.0005, -0.012};
  return k;
}

Eigen::Matrix3d R_camera_lidar_forward() {
  Eigen::Matrix3d R;
  R << 0, -1, 0,  //
      0, 0, -1,   //
      1, 0, 0;
  return R;
}

RigSpec::RigSpec() {
  // Camera positions in the LIDAR frame (x forward, y left, z up) and small mounting
  // misalignments, so that no rotation of the truth is a "nice" number.
  const Eigen::Matrix3d R_rgb = core::rotation_from_rpy(0.9 * kDeg, -1.3 * kDeg, 0.6 * kDeg) * R_camera_lidar_forward();
  const Eigen::Vector3d p_rgb_in_lidar(0.06, -0.11, 0.09);
  T_rgb_lidar = core::make_transform(R_rgb, -R_rgb * p_rgb_in_lidar);
  const Eigen::Matrix3d R_th = core::rotation_from_rpy(-0.7 * kDeg, 1.1 * kDeg, -1.4 * kDeg) * R_camera_lidar_forward();
  const Eigen::Vector3d p_th_in_lidar(0.05, 0.13, 0.10);
  T_thermal_lidar = core::make_transform(R_th, -R_th * p_th_in_lidar);

  // The paper's Dynamixel PRO gives ~12 encoder counts per degree.
  lidar.rig.motor.counts_per_revolution = 4320.0;
  lidar.rig.motor.zero_count = 2160.0;
  // The scanner's optical centre sits 4.5 cm above the tilt axis and 2 cm ahead of it,
  // with a small mounting misalignment.
  lidar.rig.T_axis_scanner =
      core::make_transform(core::rotation_from_rpy(0.25 * kDeg, -0.35 * kDeg, 0.15 * kDeg), {0.02, 0.0, 0.045});
}

std::string RigSpec::validate() const {
  std::ostringstream os;
  if (const std::string r = rgb_intrinsics.validate(); !r.empty()) return "rgb intrinsics: " + r;
  if (const std::string r = thermal_intrinsics.validate(); !r.empty()) return "thermal intrinsics: " + r;
  if (const std::string r = lidar.validate(); !r.empty()) return "lidar: " + r;
  if (const std::string r = rgb.validate(); !r.empty()) return "rgb camera: " + r;
  if (const std::string r = thermal.validate(); !r.empty()) return "thermal camera: " + r;
  if (!(rgb_fps > 0.0)) os << "rgb_fps " << rgb_fps << " must be positive";
  else if (!(thermal_fps > 0.0)) os << "thermal_fps " << thermal_fps << " must be positive";
  return os.str();
}

}  // namespace rgbdt::sim
