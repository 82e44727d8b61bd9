#pragma once
/// \file
/// The ROS camera_info YAML written by ROS camera_calibration:
///   image_width, image_height, camera_name,
///   camera_matrix {rows: 3, cols: 3, data: [9]}, distortion_model (plumb_bob|equidistant),
///   distortion_coefficients {rows: 1, cols: N, data: [N]},
///   rectification_matrix {3x3}, projection_matrix {3x4}.
#include <string>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::core {

/// Reads a camera_info YAML. Throws rgbdt::core::Error naming the file, the key and what
/// was expected when the file is missing, malformed or inconsistent.
CameraIntrinsics read_camera_info(const std::string& path);
/// Parses camera_info YAML text; `source` names it in errors.
CameraIntrinsics parse_camera_info(const std::string& yaml_text, const std::string& source);
/// Writes a camera_info YAML (identity rectification; projection = [K | 0]).
/// Throws rgbdt::core::Error if the file cannot be written.
void write_camera_info(const std::string& path, const CameraIntrinsics& intrinsics);
std::string format_camera_info(const CameraIntrinsics& intrinsics);

}  // namespace rgbdt::core
