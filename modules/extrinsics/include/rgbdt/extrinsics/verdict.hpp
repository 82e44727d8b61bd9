#pragma once
/// \file
/// The verdict on a camera-LIDAR calibration: PASS, WARN or FAIL with the reasons and the
/// numbers behind them. It checks the estimate of align_edges() five ways:
///  - residual: the RMS point-to-edge distance against the edge noise expected for the
///    camera's focal length and the board depths of the views;
///  - hole centres: each LIDAR hole (its circle) projected with the estimate against the
///    centre of the hole's ellipse in the image;
///  - agreement between views: leave-one-view-out solves started from the estimate;
///  - plausibility: solver converged, |t| within a bound, the board in front of the camera;
///  - observability: the weakest direction of the information matrix, in words.
/// FAIL rests on the residuals, the hole centres, plausibility and leave-one-view-out, none
/// of which needs the covariance; the covariance only words the weak direction (WARN).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics {

enum class VerdictLevel { kPass = 0, kWarn = 1, kFail = 2 };
std::string to_string(VerdictLevel level);  ///< "PASS", "WARN", "FAIL"

struct VerdictOptions {
  /// Largest |t| of T_camera_lidar [m] for a camera on the LIDAR's rig (--max-translation).
  double max_translation_m = 2.0;
  /// Localisation noise of a sub-pixel image edge point [px]. 1/sqrt(12) = 0.29 px is the
  /// standard deviation of rounding to the pixel grid, an upper bound for a sub-pixel
  /// detector on a sharp edge; raise it for blurred (thermal) images.
  double image_edge_sigma_px = 0.29;
  /// Placement error of a LIDAR circle [m]: the hole centre fitted to its edge points
  /// (range noise of 1-2 cm averaged over tens of points, scan-line quantisation and beam
  /// footprint leave about 1 cm). Projected with fx at the board's depth it is the larger
  /// part of the expected residual at calibration distances.
  double lidar_circle_sigma_m = 0.01;
  /// Residual RMS and hole-centre reprojection against the expected noise: WARN beyond
  /// warn_ratio x expected, FAIL beyond fail_ratio x expected. The RMS over the hundreds of
  /// circle points of a view concentrates within a few % of the noise's sigma, so 2x is
  /// already more than noise explains (marginal) and 5x is a misfit no noise level of the
  /// kind assumed above produces (the edges of another pose, a wrong intrinsic).
  double warn_ratio = 2.0;
  double fail_ratio = 5.0;
  /// Leave-one-view-out: FAIL when removing one view moves the estimate by more than this
  /// much and beyond the uncertainty of the estimate without it (lovo_chi2_bound). Beyond
  /// 2 deg or 10 cm a point at 10 m lands 35 cm / 10 cm off on the image, which no use of
  /// the calibration (colouring, fusion) tolerates: the views describe different transforms.
  /// A move that large but within that uncertainty is a WARN: the views agree, and the
  /// estimate's own covariance (and the observability check) says how loosely they pin it.
  double lovo_fail_deg = 2.0;
  double lovo_fail_cm = 10.0;
  /// Leave-one-view-out: a view is named (WARN) when its removal moves the estimate beyond
  /// the uncertainty of the estimate without it (its model covariance, without a jackknife
  /// of its own; squared Mahalanobis distance above the 99 % quantile of chi-square with 6
  /// degrees of freedom, 16.81) and by more than
  /// lovo_influence_ratio x the median move of all views (so a covariance that is too
  /// small does not name every view of a consistent session).
  double lovo_chi2_bound = 16.81;
  double lovo_influence_ratio = 3.0;
  /// Observability: WARN when the 1-sigma along the weakest direction, as the RMS motion it
  /// causes at the boards (over the circle points of the used views), exceeds this [m]. The
  /// default is the placement error of one LIDAR circle: a direction the views pin no better
  /// than one hole's fit does is not constrained by the calibration's geometry. One view always gets a WARN.
  double weak_sigma_m = 0.01;
  /// Options of the leave-one-view-out solves (the ones the estimate was made with).
  EdgeAlignmentOptions alignment;

  std::string validate() const;  ///< empty when valid, else the reason
};

/// What the verdict found in one view.
struct ViewVerdict {
  std::string name;
  bool used = true;             ///< used by the solve (not rejected as an outlier)
  double rms_px = 0.0;          ///< residual RMS at the estimate [px]
  double expected_px = 0.0;     ///< expected residual RMS at this view's depth [px]
  double board_depth_m = 0.0;   ///< depth of the board's centre in the camera frame [m]
  int holes_compared = 0;       ///< holes with a LIDAR centre and an image ellipse
  double reprojection_px = -1;  ///< RMS hole-centre reprojection error [px], -1 without holes
  /// Leave-one-view-out: the move of the estimate without this view (-1: not assessed).
  double lovo_rotation_deg = -1, lovo_translation_cm = -1;
  double lovo_mahalanobis2 = -1;  ///< squared, under the covariance of the solve without it
  bool lovo_influential = false;  ///< named: its removal moves the estimate beyond its uncertainty
  std::string problem;            ///< why this view fails or is named (empty if fine)
};

struct VerdictReason {
  VerdictLevel level = VerdictLevel::kWarn;
  std::string text;  ///< a sentence naming the number and its threshold
};

struct CalibrationVerdict {
  VerdictLevel level = VerdictLevel::kPass;
  std::vector<VerdictReason> reasons;  ///< every WARN and FAIL finding, FAIL first
  std::vector<ViewVerdict> views;      ///< same order as the input views
  int used_views = 0;
  double rms_px = 0.0;            ///< residual RMS over the used views [px]
  double expected_rms_px = 0.0;   ///< expected residual RMS over the used views [px]
  double reprojection_px = -1;    ///< RMS hole-centre reprojection over used views [px]
  double expected_reprojection_px = 0.0;
  double lovo_max_rotation_deg = -1, lovo_max_translation_cm = -1;  ///< -1: not assessed
  double translation_m = 0.0;     ///< |t| of the estimate [m]
  /// Observability (when the covariance is valid): 1-sigma along the weakest and strongest
  /// directions [m of motion at the boards], and the weakest direction in words.
  double weakest_sigma_m = -1, strongest_sigma_m = -1;
  std::string weakest_direction;  ///< e.g. "the translation along the board normal"

  bool passed() const { return level == VerdictLevel::kPass; }
  bool failed() const { return level == VerdictLevel::kFail; }
  /// "FAIL: reason; reason" / "WARN: ..." / "PASS".
  std::string summary() const;
};

/// Judges `result`, the estimate of align_edges(views, camera, options.alignment). Runs one
/// leave-one-view-out solve per used view when there are >= 3 (each ~ one solve).
/// Throws std::invalid_argument when the options are invalid or `result.views` does not
/// match `views`.
CalibrationVerdict judge_calibration(const std::vector<TargetView>& views, const core::PinholeCamera& camera,
                                     const EdgeAlignmentResult& result, const VerdictOptions& options = {});

/// Markdown section of a verdict: the level, the reasons, and a per-view table.
std::string format_verdict_report(const CalibrationVerdict& verdict);

}  // namespace rgbdt::extrinsics
