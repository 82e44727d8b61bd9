#pragma once
// What the covariance (rgbdt/extrinsics/covariance.hpp) needs of each used view at the
// solution, computed from the view's points in one pass with the Jacobian. Private to the
// module: align_edges calls it.
#include <random>
#include <vector>

#include "edge_cost.hpp"
#include "rgbdt/extrinsics/covariance.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics::detail {

struct ViewCovarianceInput {
  core::Matrix6d JtJ = core::Matrix6d::Zero();  ///< of the plain point residuals
  double r2 = 0.0;                              ///< sum of squared residuals [px^2]
  std::size_t count = 0;                        ///< points that project in front
  std::vector<core::Vector6d> hole_scores;      ///< J_h^T r_h per hole
  std::vector<core::Matrix6d> hole_systematic;  ///< B_h Sigma_h B_h^T per hole
  int holes_with_sigma = 0;                     ///< holes whose Sigma_h came from the caller
};

/// The view's points split into holes (by its lidar_centers when given, else by the gaps
/// of the circle sampling), their residuals and Jacobians at x (no robust loss), and the
/// sensitivity of the residuals to each hole's circle (centre shift, tilt of the normal).
/// sigma: the caller's per-hole uncertainty (may be null or of another length: then
/// default_range_sigma_m is used for every hole).
ViewCovarianceInput view_covariance_input(const ProjectionModel& cam, const SmoothView& field,
                                          const TargetView& view, const core::Vector6d& x,
                                          const std::vector<LidarHoleSigma>* sigma,
                                          double default_range_sigma_m);
/// The same from the view's points at x, already evaluated (as the solve's last pass
/// records them: ViewEdgeCost::accumulate).
ViewCovarianceInput view_covariance_input(const PointJacobians& at_x, const TargetView& view,
                                          const core::Vector6d& x,
                                          const std::vector<LidarHoleSigma>* sigma,
                                          double default_range_sigma_m);

/// The view's circle points with each hole's circle moved by one draw of its LIDAR error
/// (centre shift and tilt of the normal, with the covariance `sigma` gives it, as in
/// view_covariance_input): one sample of what the detection could have given.
std::vector<Eigen::Vector3d> perturbed_circle_points(const TargetView& view,
                                                     const std::vector<LidarHoleSigma>* sigma,
                                                     double default_range_sigma_m, std::mt19937_64* rng);

/// The terms and the total from the used views' inputs; when there are >= 3 of them, the
/// leave-one-view-out solutions (empty: no jackknife); with fewer, the deviations from the
/// solution of the re-solves on perturbed circles (empty: none ran).
CovarianceTerms combine_covariance(const std::vector<ViewCovarianceInput>& views,
                                   const std::vector<core::Vector6d>& leave_one_out,
                                   const std::vector<core::Vector6d>& resampled_deviations = {});

}  // namespace rgbdt::extrinsics::detail
