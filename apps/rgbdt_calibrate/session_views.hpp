#pragma once
// Glue between a calibration session on disk and the extrinsics module: loads each view's
// cloud and images, runs the calib_targets detectors and turns the detections into
// extrinsics::TargetView.
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::calibrate {

struct CameraViews {
  std::string camera_name;
  std::vector<extrinsics::TargetView> views;  ///< views where both detections succeeded
  std::vector<int> session_index;             ///< index of each view in the session
  std::vector<std::string> image_paths;       ///< image of each view
  std::vector<std::string> skipped;           ///< "view i: reason" for every other view
  int lidar_found = 0, image_found = 0;
};

using Progress = std::function<void(const std::string&)>;

/// Detects the target in every view of the session, for each requested camera (the LIDAR
/// and/or image detections seeded by session.yaml's seeds when the flags say so). The LIDAR detection of a view is shared
/// by the cameras. Throws rgbdt::core::Error naming the file when a cloud or image cannot
/// be read.
std::map<std::string, CameraViews> detect_session_views(
    const core::CalibrationSession& session, const std::map<std::string, core::PinholeCamera>& cameras,
    bool lidar_seeds, bool image_seeds, const Progress& progress);

}  // namespace rgbdt::calibrate
