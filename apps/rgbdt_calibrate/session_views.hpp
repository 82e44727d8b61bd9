#pragma once
// Glue between a calibration session on disk and the extrinsics module: loads each view's
// cloud and images, runs the calib_targets detectors and turns the detections into
// extrinsics::TargetView.
#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/covariance.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::calibrate {

struct CameraViews {
  std::string camera_name;
  std::vector<extrinsics::TargetView> views;  ///< views where both detections succeeded
  std::vector<int> session_index;             ///< index of each view in the session
  std::vector<std::string> image_paths;       ///< image of each view
  /// The decoded image of each view, kept for its overlay while all cameras' kept images
  /// stay within kOverlayImageBudgetBytes; empty: read it again from image_paths.
  std::vector<cv::Mat> images;
  /// LIDAR detection of each view (holes and method; board and edge points dropped).
  std::vector<calib_targets::LidarTargetDetection> lidar_detections;
  /// Per view, per LIDAR hole: the uncertainty of its circle from its own edge points and
  /// board plane (extrinsics::lidar_hole_sigma), for the covariance of the estimate.
  std::vector<std::vector<extrinsics::LidarHoleSigma>> hole_sigmas;
  std::vector<std::string> skipped;           ///< "view i: reason" for every other view
  /// "view i: ..." for every seed that did not lead to the target (the automatic detector
  /// was used instead, or also failed).
  std::vector<std::string> seed_notes;
  int lidar_found = 0, image_found = 0;
};

struct SessionDetections {
  std::map<std::string, CameraViews> cameras;
  std::size_t views_done = 0;  ///< views fully processed (all of them unless stopped)
  bool stopped = false;        ///< `stop` returned true before the last view
};

/// The overlays are JPEG at quality 90: pictures to look at, not data. A 1288x964 overlay
/// encodes in 5 ms to 80 kB, where the fastest PNG (zlib level 1, run-length strategy) takes
/// 79 ms and 1.4 MB; calib_end_to_end times their writing.
inline const std::vector<int> kOverlayJpegParams = {cv::IMWRITE_JPEG_QUALITY, 90};
/// The overlays' extension.
inline constexpr const char* kOverlayExtension = ".jpg";
/// Decoded images kept from detection for the overlays, all cameras together (beyond it
/// the overlays read their images again): 40 views of two 1288x964 RGB cameras.
inline constexpr std::size_t kOverlayImageBudgetBytes = std::size_t{300} << 20;

/// The view of the edge alignment from one view's LIDAR and image detections (both ok):
/// every LIDAR circle point and image edge point, and the paired hole centres/ellipses for
/// the closed-form guess when both detectors found every hole.
extrinsics::TargetView make_target_view(const calib_targets::LidarTargetDetection& lidar,
                                        const calib_targets::ImageTargetDetection& image,
                                        const core::TargetSpec& target, const cv::Size& image_size,
                                        const std::string& name);

using Progress = std::function<void(const std::string&)>;
using StopRequested = std::function<bool()>;

/// Detects the target in every view of the session, for each requested camera. Seeds of
/// session.yaml (used when the flags say so) are hints: when a seeded detection fails, the
/// automatic detector runs and the fallback is noted; when both fail, both reasons are
/// kept. The LIDAR detection of a view is shared by the cameras. A cloud or image that
/// cannot be read skips the view with the reason (naming the file). `stop` is polled
/// before each view; when it returns true the detection ends early with `stopped` set.
SessionDetections detect_session_views(const core::CalibrationSession& session,
                                       const std::map<std::string, core::PinholeCamera>& cameras,
                                       bool lidar_seeds, bool image_seeds, const Progress& progress,
                                       const StopRequested& stop = {});

}  // namespace rgbdt::calibrate
