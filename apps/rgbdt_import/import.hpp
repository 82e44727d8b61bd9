#pragma once
// rgbdt_import's work: a ROS bag streamed into a calibration or mapping session folder
// (design.md's file contracts).
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/core/session.hpp"

namespace rgbdt::import {

enum class SessionKind { kCalibration, kMapping };

struct CameraSource {
  std::string name;        ///< session camera name, e.g. "rgb"
  std::string topic;       ///< Image or CompressedImage topic
  std::string info_topic;  ///< CameraInfo topic; empty: the image topic's sibling camera_info
  std::string intrinsics;  ///< camera_info YAML file to copy instead of a CameraInfo topic
  /// Counts -> kelvin of a thermal camera, written to session.yaml (a bag does not carry it).
  std::optional<core::RadiometrySpec> radiometry;
};

struct ImportOptions {
  std::filesystem::path bag;
  std::filesystem::path out;  ///< the session folder; must not exist or be empty
  SessionKind kind = SessionKind::kMapping;
  std::string lidar_topic;
  std::vector<CameraSource> cameras;
  std::string imu_topic;          ///< empty: no IMU
  std::optional<double> start_s;  ///< [s] from the bag's first message
  std::optional<double> end_s;    ///< [s] from the bag's first message
  /// Calibration: the session's target entry as YAML, e.g. "{type: circle_hole, radius: 0.3}".
  std::string target_yaml;
  /// Calibration: frames continue a still run while they differ from the previous frame by
  /// less than this [mean grey levels of 0..255 on a downscaled frame].
  double still_threshold = 2.0;
  /// Calibration: still runs of fewer frames are dropped.
  int min_still_frames = 5;
  /// Calibration: the camera whose frames decide stillness; empty: the first camera.
  std::string still_camera;
  /// Calibration: the most points one view may accumulate (memory bound).
  std::size_t max_view_points = 20000000;
};

/// Thrown when Ctrl-C stops the import; the partial session has been removed.
struct Interrupted {};

struct ImportResult {
  std::size_t messages = 0;
  std::size_t clouds = 0;  ///< mapping: clouds written; calibration: clouds accumulated
  std::size_t views = 0;   ///< calibration
  std::size_t imu_samples = 0;
  std::vector<std::pair<std::string, std::size_t>> frames;  ///< camera -> frames written
};

/// Imports the bag: checks every topic first (errors name the topic, its type and the bag),
/// streams the messages (progress on stderr at most once a second), writes the session into
/// a temporary sibling of `out` and renames it to `out` at the end. Calibration prints one
/// line per still interval to `report`. Throws core::Error or std::invalid_argument on bad
/// input, Interrupted on Ctrl-C; the temporary folder is removed then.
ImportResult import_bag(const ImportOptions& options, std::FILE* report);

}  // namespace rgbdt::import
