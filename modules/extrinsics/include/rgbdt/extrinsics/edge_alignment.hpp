#pragma once
/// \file
/// Camera-LIDAR extrinsics by aligning the LIDAR circle edges with the image edges of the
/// target (paper Sec. 3.6, Eq. (2)):
///   T* = argmin_T sum_j sum_i rho( d_j( project(K, T * E_j^i) )^2 )
/// where d_j is the distance field of the image edges of view j.
///
/// Two methods:
///  - kSmoothField (default, ours): exact sub-pixel distance field (EdgeDistanceField),
///    bicubic interpolation (ceres::BiCubicInterpolator), an exact analytic Jacobian through
///    the full projection with distortion (core::project_generic's model), Huber loss,
///    coarse-to-fine over the circle points, outlier views rejected by their residual,
///    closed-form initial guess when none is given.
///  - kPaperPlaneFit (the paper's exact variant, for comparison): cv::distanceTransform of
///    the rasterised edges, a least-squares plane fitted on the 10x10 window around each
///    pixel the points fall on (cached in a look-up table), central numeric differences,
///    no robust loss.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/extrinsics/covariance.hpp"
#include "rgbdt/extrinsics/edge_distance_field.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics {

enum class EdgeAlignmentMethod {
  kSmoothField,    ///< ours: smooth field, exact derivatives, robust loss ("edge")
  kPaperPlaneFit,  ///< paper Sec. 3.6: 10x10 plane-fit LUT, central differences ("paper")
};
/// "edge" / "paper"; the parser throws std::invalid_argument naming the value otherwise.
std::string to_string(EdgeAlignmentMethod method);
EdgeAlignmentMethod edge_alignment_method_from_string(const std::string& name);

struct EdgeAlignmentOptions {
  EdgeAlignmentMethod method = EdgeAlignmentMethod::kSmoothField;
  /// Huber width on the point-to-edge distance [px] (kSmoothField). Points further than
  /// this from an edge count linearly, so stray circle points cannot dominate. 0 = none.
  double huber_px = 2.0;
  int max_iterations = 100;           ///< Levenberg-Marquardt iterations per solve
  double function_tolerance = 1e-10;  ///< relative cost change that ends the solve
  double parameter_tolerance = 1e-10; ///< relative step size that ends the solve
  /// The polish on all points (kSmoothField, coarse_stride > 1) also ends when its next
  /// step would move the pose by less than this many standard deviations of the estimate
  /// (its Mahalanobis length under the covariance): it takes that step without evaluating
  /// it (Gauss-Newton's quadratic model is exact to second order that close; the step
  /// after it would be a few percent as long) and saves a pass over all points. The fit
  /// and the covariance are those of the last pass, this short step away. A step shorter
  /// than 5x this that raises the cost ends the polish where it is: the cost is not smooth
  /// at that scale (projections crossing the field's band edge or from one edge point's
  /// cell to the next), and damping it further would spend passes on nothing it resolves.
  /// 0 = off (both rules).
  double step_tolerance_sigma = 0.05;
  EdgeFieldOptions field;             ///< distance field (kSmoothField)
  /// Before Eq. (2), refine the start by projecting the LIDAR hole centres onto the image
  /// ellipse centres (needs >= 3 holes with both). Widens the basin of convergence from a
  /// poor user guess; turn off to study Eq. (2) alone. (Not used by kPaperPlaneFit.)
  bool coarse_center_stage = true;
  /// Coarse-to-fine (kSmoothField): each solve first runs on every coarse_stride-th circle
  /// point of each view, then polishes on all points (same minimum, a fraction of the
  /// cost). 1 solves on all points from the start.
  int coarse_stride = 16;
  /// Window of the paper's plane fit [px] (kPaperPlaneFit); the paper uses 10.
  int paper_window_px = 10;

  /// Outlier views: after a solve, a view whose RMS distance exceeds
  /// max(outlier_min_rms_px, outlier_rms_ratio * median RMS of all views) is removed and
  /// the problem solved again (repeated until no view is removed). Raise these when the
  /// edges are noisy (thermal images, blurred edges).
  double outlier_rms_ratio = 4.0;
  double outlier_min_rms_px = 3.0;
  bool reject_outlier_views = true;
  /// A view is unusable when fewer than this fraction of its circle points project into
  /// the image at the initial guess and again at the solution.
  double min_in_image_fraction = 0.5;
  /// Fill EdgeAlignmentResult::covariance (see covariance.hpp: image-edge noise, the
  /// correlation along an edge, the LIDAR circles' own uncertainty and, with >= 3 views,
  /// the leave-one-view-out scatter). Costs one pass with the Jacobian over the points and,
  /// with the jackknife, one polish per used view.
  bool compute_covariance = true;
  /// The LIDAR hole uncertainties per view and the jackknife switch of the covariance.
  CovarianceOptions covariance_model;

  std::string validate() const;  ///< empty when valid, else the reason
};

/// Fit of one view at the solution.
struct ViewResidual {
  std::string name;
  int num_points = 0;         ///< LIDAR circle points
  int num_in_image = 0;       ///< of which project into the image
  double rms_px = 0.0;        ///< RMS point-to-edge distance [px] at the solution
  double median_px = 0.0;     ///< median point-to-edge distance [px]
  bool used = true;           ///< false when rejected (see reason)
  std::string reason;         ///< why the view was rejected (empty when used)
};

struct EdgeAlignmentResult {
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();  ///< LIDAR -> camera
  Eigen::Isometry3d T_camera_lidar_initial = Eigen::Isometry3d::Identity();  ///< start
  bool initial_from_closed_form = false;  ///< true when no guess was given
  /// Set when the closed-form start had a rival pose far from it that fits about as well (a
  /// symmetric hole layout seen from too few poses): what the rival is and what was assumed.
  std::string initial_guess_ambiguity;
  core::Matrix6d covariance = core::Matrix6d::Zero();  ///< [rx ry rz tx ty tz], rad^2, m^2
  bool covariance_valid = false;  ///< computed and full rank (every parameter observable)
  /// The terms `covariance` (== covariance_terms.total) is made of; .jacobian is the
  /// residual-scaled (J^T J)^-1 alone, which ignores everything but image-edge noise.
  CovarianceTerms covariance_terms;
  bool converged = false;      ///< solver reached a tolerance (not max_iterations/failure)
  int iterations = 0;          ///< LM iterations, summed over outlier-rejection rounds
  double rms_px = 0.0;         ///< RMS point-to-edge distance over the used views [px]
  std::vector<ViewResidual> views;  ///< same order as the input views
  double solve_time_s = 0.0;   ///< wall time of the whole call
  /// Wall time [s] of the call's steps (the rest of solve_time_s is checks and copies).
  struct StageTimes {
    double initial_guess_s = 0.0;  ///< the closed-form start (0 when a guess is given)
    double fields_s = 0.0;         ///< the exact edge fields, which both methods read
    double paper_luts_s = 0.0;     ///< the paper's plane-fit LUTs (its method only)
    double alignment_s = 0.0;      ///< hole centres, the rounds of Eq. (2), view fits, rejection
    double covariance_s = 0.0;     ///< the covariance at the solution
  };
  StageTimes stage_times;
  std::string message;         ///< why the solver stopped, outliers, etc.

  /// Indices of views rejected as outliers or unusable.
  std::vector<int> outlier_views() const;
};

/// Estimates T_camera_lidar from the views. Without an initial guess the closed-form
/// estimate of initial_guess.hpp is used. Throws std::invalid_argument for invalid
/// options and when no view is usable (the message lists every view's reason).
EdgeAlignmentResult align_edges(const std::vector<TargetView>& views,
                                const core::PinholeCamera& camera,
                                const EdgeAlignmentOptions& options = {},
                                std::optional<Eigen::Isometry3d> T_camera_lidar_guess = {});

/// Point-to-edge distances [px] of a view's circle points under a transform (points that do
/// not project in front of the camera get +infinity). Uses the exact field.
std::vector<double> point_to_edge_distances(const TargetView& view,
                                            const core::PinholeCamera& camera,
                                            const Eigen::Isometry3d& T_camera_lidar);

}  // namespace rgbdt::extrinsics
