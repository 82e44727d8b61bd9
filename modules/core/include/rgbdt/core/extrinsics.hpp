#pragma once
/// \file
/// The extrinsics YAML of design.md:
///   parent_frame: camera          # frame the points are mapped into
///   child_frame: lidar            # frame the points come from
///   translation: [x, y, z]        # metres
///   rotation_quaternion: [x, y, z, w]
///   matrix: [16 numbers, row major]
///   covariance: [36 numbers, row major, order rx ry rz tx ty tz]   # optional
/// T_parent_child maps points from child_frame into parent_frame (T_camera_lidar).
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::core {

struct Extrinsics {
  std::string parent_frame = "camera";
  std::string child_frame = "lidar";
  Eigen::Isometry3d T_parent_child = Eigen::Isometry3d::Identity();
  std::optional<Matrix6d> covariance;  ///< [rx ry rz tx ty tz], rad^2 / m^2
};

/// Reads the YAML. Either translation + rotation_quaternion or matrix must be present;
/// when both are, they must agree (1e-6). Throws rgbdt::core::Error naming the file, the
/// key and what was expected.
Extrinsics read_extrinsics(const std::string& path);
Extrinsics parse_extrinsics(const std::string& yaml_text, const std::string& source);
void write_extrinsics(const std::string& path, const Extrinsics& extrinsics);
std::string format_extrinsics(const Extrinsics& extrinsics);

}  // namespace rgbdt::core
