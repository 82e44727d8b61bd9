#pragma once
/// \file
/// The session.yaml files of design.md: calibration sessions and mapping sessions.
/// Readers resolve every relative path against the folder that holds session.yaml, so the
/// structs carry absolute paths; writers store paths relative to that folder when they lie
/// below it.
///
/// The readers check every value (errors name the file, the key path, the value and what
/// was expected): the target radius finite in (0, 5] m, board_size finite in (0, 20] m and
/// larger than the holes, holes finite and on the board, camera names safe as file names
/// (is_valid_camera_name), the cameras of views and seeds declared under `cameras`, seeds
/// finite, and no path naming a folder where a file is expected. They do not open the
/// files a session names: preflight_problems() checks those, all at once.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rgbdt::core {

/// The calibration target.
///   target: {type: circle_hole, radius: 0.30}
///   target: {type: circle_hole, radius: 0.12, board_size: [1.0, 0.8],
///            holes: [[-0.25, 0.2], [0.25, 0.2], [-0.25, -0.2], [0.25, -0.2]]}
/// `holes` are hole centres in the board's own frame [m] (x right, y up, origin at the
/// board centre); absent means one hole at the origin.
struct TargetSpec {
  std::string type = "circle_hole";
  double radius_m = 0.0;
  std::optional<Eigen::Vector2d> board_size_m;
  std::vector<Eigen::Vector2d> holes_m;
};

/// How a thermal camera's counts map to temperature, e.g.
///   radiometry: {type: linear, kelvin_per_count: 0.04, offset_k: 0.0}
/// Parameters are kept by name; the thermal_camera module interprets them.
struct RadiometrySpec {
  std::string type = "linear";
  std::map<std::string, double> parameters;  ///< every value finite
  /// Where the entry came from, for errors, e.g. "/s/session.yaml: cameras.thermal.radiometry"
  /// (empty when built in code).
  std::string source;
};

struct CameraEntry {
  std::string intrinsics;  ///< absolute path of the camera_info YAML
  std::string frames;      ///< absolute path of the frame index CSV (mapping sessions); empty: no frames
  std::optional<RadiometrySpec> radiometry;
};

struct CalibrationView {
  std::string cloud;                          ///< absolute path of the PCD
  std::map<std::string, std::string> images;  ///< camera name -> absolute PNG path
  std::map<std::string, Eigen::Vector2d> image_seeds;  ///< camera -> seed pixel (optional)
  std::optional<Eigen::Vector3d> lidar_seed;           ///< seed point [m], LIDAR frame
};

struct CalibrationSession {
  std::string directory;  ///< absolute folder of session.yaml
  TargetSpec target;
  std::map<std::string, CameraEntry> cameras;
  std::vector<CalibrationView> views;
};

struct LidarStream {
  std::string rawlog;  ///< absolute path of an MRPT rawlog, or empty
  std::string clouds;  ///< absolute path of a CSV index of assembled clouds, or empty
  std::string rig;     ///< absolute path of tilt_rig.yaml (rgbdt/core/tilt_rig.hpp), or empty
};

/// An IMU beside the LIDAR: `imu: {samples: imu.csv, rotation_lidar_imu: [qx, qy, qz, qw]}`.
struct ImuStream {
  /// Absolute path of the CSV time_s,wx,wy,wz,ax,ay,az (rad/s, m/s^2, the IMU's axes).
  std::string samples;
  /// The IMU's axes in the LIDAR frame (optional in the file: identity, the axes agree).
  Eigen::Quaterniond rotation_lidar_imu = Eigen::Quaterniond::Identity();
};

struct MappingSession {
  std::string directory;
  LidarStream lidar;
  std::map<std::string, CameraEntry> cameras;
  std::string trajectory;  ///< optional CSV of the cart trajectory (absolute), or empty
  std::optional<ImuStream> imu;  ///< optional
};

/// True for names usable as file names: 1 to 64 characters of [A-Za-z0-9_-].
bool is_valid_camera_name(const std::string& name);

/// Reads a calibration session from a session.yaml file or the folder that holds it.
/// Throws rgbdt::core::Error naming the file, the key, the value and what was expected.
CalibrationSession read_calibration_session(const std::string& path);
/// Parses session.yaml text as if read from `yaml_path` (which need not exist); relative
/// paths resolve against its folder.
CalibrationSession parse_calibration_session(const std::string& yaml_text, const std::string& yaml_path);
/// Writes atomically (rgbdt/core/output.hpp); throws rgbdt::core::Error naming the path.
void write_calibration_session(const std::string& yaml_path, const CalibrationSession& session);

/// A mapping session may have no cameras (a LIDAR-only map): `cameras` may be absent or empty.
MappingSession read_mapping_session(const std::string& path);
MappingSession parse_mapping_session(const std::string& yaml_text, const std::string& yaml_path);
void write_mapping_session(const std::string& yaml_path, const MappingSession& session);

/// Every problem with the files a session names, all at once (empty when none): missing
/// files, folders or empty files where files are expected, camera_info, tilt_rig and time
/// index files that do not read, index rows naming missing files, a cloud index without
/// rows. Each entry names the path, the session key that names it and what was expected;
/// no entry quotes the content of a file. Apps print them all before the long work.
std::vector<std::string> preflight_problems(const CalibrationSession& session);
std::vector<std::string> preflight_problems(const MappingSession& session);

}  // namespace rgbdt::core
