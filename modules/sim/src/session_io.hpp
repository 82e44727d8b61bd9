#pragma once
// Writers shared by the session generators (private to the sim module).
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "rgbdt/sim/rig.hpp"

namespace rgbdt::sim::detail {

/// Creates a folder (and parents); throws core::Error naming it on failure.
void make_dirs(const std::string& path);
/// cv::imwrite that throws core::Error naming the file on failure.
void write_png(const std::string& path, const cv::Mat& image);
/// Writes emitter text to a file; throws core::Error on failure.
void save_yaml(const std::string& path, const YAML::Emitter& out);
void save_text(const std::string& path, const std::string& text);

/// Emits {parent_frame, child_frame, translation, rotation_quaternion, matrix} as a flow map.
void emit_extrinsics(YAML::Emitter& out, const std::string& parent, const std::string& child,
                     const Eigen::Isometry3d& T_parent_child);
/// Emits {translation, rotation_quaternion} as a flow map.
void emit_pose(YAML::Emitter& out, const Eigen::Isometry3d& T);
void emit_vector(YAML::Emitter& out, const Eigen::Vector3d& v);

/// The rig with every noise multiplied by scale.
RigSpec scale_noise(const RigSpec& rig, double scale);

/// Writes rgb.yaml and thermal.yaml into dir and the true calibration under dir/true_calib/
/// (extrinsics_rgb.yaml, extrinsics_thermal.yaml, rgb.yaml, thermal.yaml, report.md).
/// `what` describes the session in the report.
void write_true_calibration(const std::string& dir, const RigSpec& rig, const std::string& what);

/// Emits the common part of ground_truth.yaml: extrinsics, intrinsics and lidar keys.
/// rig_file is empty for sessions without a tilt_rig.yaml key.
void emit_ground_truth_header(YAML::Emitter& out, const RigSpec& rig, const std::string& rig_file);

/// "000", "001", ...
std::string index_name(int i, int digits = 3);

}  // namespace rgbdt::sim::detail
