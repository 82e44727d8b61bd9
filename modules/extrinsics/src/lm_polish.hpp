#pragma once
// The polish of our Eq. (2) solve on all circle points, from inside the basin (after the
// coarse solve): Levenberg-Marquardt on 6x6 normal equations accumulated point by point.
// Private to the module.
#include <vector>

#include "edge_cost.hpp"

namespace rgbdt::extrinsics::detail {

struct PolishOptions {
  int max_iterations = 100;            ///< LM steps tried, accepted or not
  double parameter_tolerance = 1e-10;  ///< stop when |dx| < tol (|x| + tol)
  double gradient_tolerance = 1e-14;   ///< stop when max |J^T r| (scaled) < tol
  /// Take the next step without evaluating it, and stop, when it is shorter than this many
  /// standard deviations of the estimate (Mahalanobis length under sigma^2 (J^T J)^-1);
  /// 0 = off.
  double step_tolerance_sigma = 0.0;
  /// Stop at x when a step shorter than this many standard deviations (as above) is
  /// rejected: the cost went up along a direction its own model says goes down, so it is
  /// not smooth at that scale (a projection crossing the field's band edge or passing from
  /// one edge point's cell to the next), and damping the step further only spends passes
  /// on what the cost cannot resolve. 0 = off (LM damps and retries).
  double rejected_step_sigma = 0.0;
  /// Record every point's Huber-free residual and Jacobian in each evaluation, so that the
  /// result carries them at x (PolishResult::points).
  bool keep_point_jacobians = false;
};

struct PolishResult {
  core::Vector6d x = core::Vector6d::Zero();  ///< the pose where the solve stopped
  /// The last pose evaluated: x, or x less a last step shorter than step_tolerance_sigma.
  /// normal_equations, fits and points below are at this pose.
  core::Vector6d x_evaluated = core::Vector6d::Zero();
  int iterations = 0;          ///< LM steps tried, including the final too-small one
  bool converged = false;      ///< a tolerance was reached (not max_iterations)
  double initial_cost = 0.0;   ///< 1/2 |r|^2 at the start
  double final_cost = 0.0;     ///< 1/2 |r|^2 at x_evaluated
  /// Per cost (same order as the input), at x_evaluated: the normal equations (their JtJ_plain() is
  /// the covariance's) and the fit of the points. Every evaluation computes both, so the
  /// last accepted one serves the per-view fit and the covariance without another pass.
  std::vector<NormalEquations> normal_equations;
  std::vector<PointFit> fits;
  /// Per cost, at x_evaluated, when PolishOptions::keep_point_jacobians (else empty).
  std::vector<PointJacobians> points;
};

/// Minimises the stacked residuals of the costs from x0. Each evaluation is one pass over
/// the points with the Jacobian (near the minimum almost every step is accepted, so the
/// residual-only pass of a classic LM step would be a pass more per step).
PolishResult polish(const std::vector<const ViewEdgeCost*>& costs, const core::Vector6d& x0,
                    const PolishOptions& options);

}  // namespace rgbdt::extrinsics::detail
