#pragma once
/// \file
/// Intrinsic calibration of RGB and thermal cameras from planar patterns (paper Sec. 3.1:
/// 40 views, 0.24 px with RADOCC), made robust for thermal images: percentile
/// normalisation of 16-bit data, both polarities, several detectors, corner refinement on
/// the normalised float image, unreliable views rejected with the reason, and the
/// distortion terms chosen by cross-validation over views instead of fitting k3 blindly.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::calib_targets {

enum class PatternType { kCheckerboard, kCircles, kAsymmetricCircles };

/// "checkerboard", "circles", "acircles"; throws std::invalid_argument naming the value.
PatternType pattern_type_from_string(const std::string& name);
std::string to_string(PatternType type);

struct PatternSpec {
  PatternType type = PatternType::kCheckerboard;
  int cols = 0;           ///< inner corners (checkerboard) or circles per row
  int rows = 0;           ///< inner corners or circles per column
  double spacing_m = 0.0; ///< square size, or circle centre spacing [m]
  std::string validate() const;
  /// Board-frame points (z = 0) in OpenCV's detection order.
  std::vector<cv::Point3f> object_points() const;
};

struct PatternDetection {
  bool ok = false;
  std::string reason;               ///< why not found
  std::vector<cv::Point2f> points;  ///< [px] in object_points() order
  bool inverted = false;            ///< found on the inverted image (e.g. black squares warm)
  std::string method;               ///< detector that succeeded
};

struct PatternDetectionOptions {
  double low_percentile = 0.5;    ///< normalisation of 16-bit / low-contrast images
  double high_percentile = 99.5;
  bool try_inverted = true;       ///< both polarities
  bool try_clahe = true;          ///< local contrast equalisation as a further attempt
  bool try_upscale = true;        ///< 2x upscaled attempt for small patterns
  int subpix_window_px = 5;       ///< cornerSubPix half window (classic checkerboard detector only)
  std::string validate() const;
};

/// Finds the pattern in an 8U/16U image, 1 or 3 channels. Never throws for bad images.
PatternDetection detect_pattern(const cv::Mat& image, const PatternSpec& pattern,
                                const PatternDetectionOptions& options = {});

struct IntrinsicsOptions {
  core::DistortionModel model = core::DistortionModel::kPlumbBob;  ///< or kEquidistant
  /// Choose the distortion terms by K-fold cross-validation over views (reprojection error
  /// of held-out views, posed with solvePnP); when false, fit all terms of the model.
  bool select_distortion = true;
  int folds = 4;
  /// A richer model must lower the held-out error by this fraction to be preferred.
  double min_improvement = 0.02;
  /// Views whose RMS exceeds max(outlier_factor * median, max_view_rms_px) are rejected.
  double outlier_factor = 3.0;
  double max_view_rms_px = 1.0;
  int min_views = 5;
  std::string validate() const;
};

struct ViewResult {
  std::string name;
  bool used = false;
  std::string reason;  ///< why rejected
  double rms_px = 0.0;
  std::vector<cv::Point2f> points, reprojected;
};

struct ModelCandidate {
  std::string terms;        ///< e.g. "k1 k2", "k1 k2 p1 p2 k3"
  double heldout_rms_px = 0.0;
  double train_rms_px = 0.0;
};

struct IntrinsicsResult {
  bool ok = false;
  std::string reason;
  core::CameraIntrinsics intrinsics;
  std::vector<std::string> parameter_names;  ///< fx fy cx cy then the distortion terms
  std::vector<double> parameters, std_devs;  ///< 1-sigma, same order
  double rms_px = 0.0;
  std::string distortion_terms;              ///< the terms that were estimated
  std::vector<ModelCandidate> candidates;    ///< cross-validation table
  std::vector<ViewResult> views;             ///< every input view, used or not
  double coverage = 0.0;  ///< fraction of an 8x8 image grid with detected points
};

/// Calibrates from detections (one per view; failed ones are reported as rejected).
IntrinsicsResult calibrate_intrinsics(const std::vector<PatternDetection>& detections,
                                      const std::vector<std::string>& names, cv::Size image_size,
                                      const PatternSpec& pattern,
                                      const IntrinsicsOptions& options = {});

}  // namespace rgbdt::calib_targets
