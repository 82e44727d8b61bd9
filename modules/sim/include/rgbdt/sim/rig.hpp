#pragma once
/// \file
/// The simulated sensor rig: true intrinsics of the RGB and thermal cameras, true
/// extrinsics T_camera_lidar, the tilting LIDAR and the camera timing. Defaults follow
/// the paper's rig (design.md "Sensor defaults"); the cameras sit 10-20 cm from the tilt
/// axis, looking forward (camera z = LIDAR x).
#include <Eigen/Geometry>
#include <string>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/sim/camera_sim.hpp"
#include "rgbdt/sim/lidar_sim.hpp"

namespace rgbdt::sim {

/// PointGrey CM3-U3-13S2M with a 4.8 mm lens: 1288x964, fx ~ 1335 px, mild barrel distortion.
core::CameraIntrinsics default_rgb_intrinsics();
/// FLIR Tau2 640 with a 7.5 mm lens: 640x512, fx ~ 417 px, stronger barrel distortion.
core::CameraIntrinsics default_thermal_intrinsics();

/// Rotation that turns the LIDAR axes (x forward, y left, z up) into camera axes
/// (x right, y down, z forward): the R of T_camera_lidar for a camera looking forward.
Eigen::Matrix3d R_camera_lidar_forward();

struct RigSpec {
  core::CameraIntrinsics rgb_intrinsics = default_rgb_intrinsics();
  core::CameraIntrinsics thermal_intrinsics = default_thermal_intrinsics();
  Eigen::Isometry3d T_rgb_lidar;      ///< maps LIDAR points into the RGB camera frame
  Eigen::Isometry3d T_thermal_lidar;  ///< maps LIDAR points into the thermal camera frame
  TiltLidarOptions lidar;
  RgbCameraOptions rgb;
  ThermalCameraOptions thermal;
  double rgb_fps = 5.0;       ///< frames per second
  double thermal_fps = 25.0;  ///< frames per second

  RigSpec();  ///< the default rig (see the .cpp for the numbers)
  std::string validate() const;
};

}  // namespace rgbdt::sim
