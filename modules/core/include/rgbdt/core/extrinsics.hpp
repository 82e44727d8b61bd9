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
///
/// Frames. rgbdt's own files name the camera as parent_frame and the LIDAR as child_frame
/// (T_camera_lidar, "transforming points from the LIDAR frame into the camera frame"). A
/// file written the other way round (parent_frame: lidar, child_frame: rgb, a T_lidar_rgb)
/// is honoured: the readers return it inverted, with the frames swapped, so that
/// T_parent_child is always T_camera_lidar when one frame is a LIDAR frame. A file between
/// two cameras (parent_frame: thermal, child_frame: rgb) is returned as written.
/// Every number must be finite, the quaternion of unit norm (within 1e-3), the matrix a
/// rigid transform that agrees with translation + quaternion when both are given, and the
/// covariance symmetric and positive semi-definite.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::core {

struct Extrinsics {
  std::string parent_frame = "camera";
  std::string child_frame = "lidar";
  Eigen::Isometry3d T_parent_child = Eigen::Isometry3d::Identity();
  std::optional<Matrix6d> covariance;  ///< [rx ry rz tx ty tz], rad^2 / m^2
};

/// The frames a camera-LIDAR extrinsics file must name.
struct ExtrinsicsFrames {
  /// The camera's frame (its session name, e.g. "rgb"); empty accepts any frame that is
  /// not a LIDAR frame.
  std::string camera;
  /// Names of the LIDAR frame (compared without regard to case; a "_link" or "_frame"
  /// suffix is ignored).
  std::vector<std::string> lidar = {"lidar", "laser", "scanner", "hokuyo", "velodyne"};
};

/// True when `frame` is one of frames.lidar (see ExtrinsicsFrames::lidar).
bool is_lidar_frame(const std::string& frame, const ExtrinsicsFrames& frames = {});

/// Reads the YAML. Either translation + rotation_quaternion or matrix must be present;
/// when both are, they must agree (1e-6). A file whose parent_frame is a LIDAR frame
/// (default names) and whose child_frame is not is returned inverted (see the file
/// comment). Throws rgbdt::core::Error naming the file, the key, the value and what was
/// expected.
Extrinsics read_extrinsics(const std::string& path);
Extrinsics parse_extrinsics(const std::string& yaml_text, const std::string& source);
/// Reads a camera-LIDAR file and returns T_camera_lidar (parent_frame = the camera,
/// child_frame = the LIDAR frame), inverting a file that stores T_lidar_camera. With
/// frames.camera set, a file naming that camera as one frame takes the other as the LIDAR,
/// whatever it is called; otherwise the LIDAR frame must be one of frames.lidar. Refuses a
/// file whose frames are not the LIDAR and the expected camera.
Extrinsics read_extrinsics(const std::string& path, const ExtrinsicsFrames& frames);
Extrinsics parse_extrinsics(const std::string& yaml_text, const std::string& source,
                            const ExtrinsicsFrames& frames);
/// The same transform seen from the other side: T_child_parent, frames swapped, the
/// covariance of to_vector6 carried over to first order.
Extrinsics inverted(const Extrinsics& extrinsics);
/// Writes atomically (rgbdt/core/output.hpp); throws rgbdt::core::Error naming the path.
void write_extrinsics(const std::string& path, const Extrinsics& extrinsics);
std::string format_extrinsics(const Extrinsics& extrinsics);

}  // namespace rgbdt::core
