#include "lm_polish.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace rgbdt::extrinsics::detail {

namespace {

struct Evaluation {
  std::vector<NormalEquations> per_cost;
  std::vector<PointFit> fits;
  std::vector<PointJacobians> points;  // when kept
  NormalEquations total;
};

void evaluate(const std::vector<const ViewEdgeCost*>& costs, const core::Vector6d& x, bool keep_points,
              Evaluation* e) {
  e->per_cost.assign(costs.size(), NormalEquations{});
  e->fits.resize(costs.size());
  e->points.resize(keep_points ? costs.size() : 0);
  e->total = NormalEquations{};
  for (size_t k = 0; k < costs.size(); ++k) {
    costs[k]->accumulate(x.data(), &e->per_cost[k], &e->fits[k], keep_points ? &e->points[k] : nullptr);
    e->total += e->per_cost[k];
  }
}

}  // namespace

PolishResult polish(const std::vector<const ViewEdgeCost*>& costs, const core::Vector6d& x0,
                    const PolishOptions& options) {
  PolishResult result;
  core::Vector6d x = x0;
  result.x_evaluated = x0;
  Evaluation current, candidate;
  evaluate(costs, x, options.keep_point_jacobians, &current);
  result.initial_cost = 0.5 * current.total.r2;

  // Jacobi scaling from the start, 1 / (1 + |column of J|), fixed for the solve (as
  // ceres::TinySolver): the steps are solved for in scaled parameters, so that rotation
  // [rad] and translation [m] are regularised alike.
  const core::Vector6d scaling =
      (1.0 + current.total.JtJ.diagonal().array().sqrt()).inverse().matrix();
  const auto scaled_system = [&](const NormalEquations& ne, core::Matrix6d* A, core::Vector6d* g) {
    *A = scaling.asDiagonal() * ne.JtJ * scaling.asDiagonal();
    *g = -(scaling.asDiagonal() * ne.Jtr);  // the descent direction's right-hand side
  };
  core::Matrix6d A;
  core::Vector6d g;
  scaled_system(current.total, &A, &g);

  long num_points = 0;
  for (const ViewEdgeCost* c : costs) num_points += c->num_points();
  bool stopped = g.cwiseAbs().maxCoeff() < options.gradient_tolerance;
  // Levenberg-Marquardt damping u with Nielsen's update (factor v on rejection).
  double u = 1e-4, v = 2.0;
  while (!stopped && result.iterations < options.max_iterations) {
    ++result.iterations;
    core::Matrix6d A_damped = A;
    for (int i = 0; i < 6; ++i) A_damped(i, i) += u * std::clamp(A(i, i), 1e-6, 1e32);
    const core::Vector6d step = A_damped.ldlt().solve(g);
    const core::Vector6d dx = scaling.asDiagonal() * step;
    if (dx.norm() < options.parameter_tolerance * (x.norm() + options.parameter_tolerance)) {
      stopped = true;
      break;
    }
    // The step's squared length in standard deviations of the estimate: |dx|^2 over the
    // covariance sigma^2 (J^T J)^-1 is step^T A step / sigma^2, sigma^2 = |r|^2 / (points - 6)
    // (0 with too few points; both rules below then stay off).
    const double step_sigma2 =
        num_points > 6 ? step.dot(A * step) / (current.total.r2 / static_cast<double>(num_points - 6)) : 0.0;
    // So short a step is taken without evaluating it: the quadratic model that predicts it
    // is exact to second order there (the next step would be a few percent of it), and its
    // evaluation would cost a pass over all points.
    if (options.step_tolerance_sigma > 0.0 && num_points > 6) {
      const double tol = options.step_tolerance_sigma;
      if (step_sigma2 < tol * tol) {
        result.x_evaluated = x;
        x += dx;
        stopped = true;
        break;
      }
    }
    const core::Vector6d x_new = x + dx;
    evaluate(costs, x_new, options.keep_point_jacobians, &candidate);
    // Gain ratio: actual over predicted reduction of |r|^2.
    const double actual = current.total.r2 - candidate.total.r2;
    const double predicted = step.dot(2.0 * g - A * step);
    const double rho = actual / predicted;
    if (rho > 0.0) {
      x = x_new;
      result.x_evaluated = x;
      std::swap(current, candidate);
      scaled_system(current.total, &A, &g);
      if (g.cwiseAbs().maxCoeff() < options.gradient_tolerance) stopped = true;
      const double c = 2.0 * rho - 1.0;
      u *= std::max(1.0 / 3.0, 1.0 - c * c * c);
      v = 2.0;
    } else {
      const double stop = options.rejected_step_sigma;
      if (stop > 0.0 && num_points > 6 && step_sigma2 < stop * stop) {
        stopped = true;
        break;
      }
      u *= v;
      v *= 2.0;
    }
  }
  result.x = x;
  result.converged = stopped;
  result.final_cost = 0.5 * current.total.r2;
  result.normal_equations = std::move(current.per_cost);
  result.fits = std::move(current.fits);
  result.points = std::move(current.points);
  return result;
}

}  // namespace rgbdt::extrinsics::detail
