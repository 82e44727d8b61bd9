#pragma once
// Eq. (2) cost of one view for Ceres, ours (kSmoothField): the residual of every LIDAR
// circle point is the 2-vector from the image edge to its projection (its norm is the
// point-to-edge distance), with the Huber loss folded in. Private to the module; the tests
// include it to check the analytic Jacobian against automatic differentiation.
#include <ceres/ceres.h>
#include <ceres/cubic_interpolation.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <vector>

#include "rgbdt/core/transform.hpp"

#include "projection.hpp"
#include "rgbdt/extrinsics/edge_distance_field.hpp"

namespace rgbdt::extrinsics::detail {

inline double value_of(double x) { return x; }
template <typename J>
double value_of(const J& jet) {
  return jet.a;
}

/// p_camera = R(x[0..2]) p_lidar + x[3..5] (angle-axis rotation), generic for autodiff.
template <typename T>
void transform_point(const T* x, const Eigen::Vector3d& p_lidar, T* p_camera) {
  const T p[3] = {T(p_lidar.x()), T(p_lidar.y()), T(p_lidar.z())};
  ceres::AngleAxisRotatePoint(x, p, p_camera);
  p_camera[0] += x[3];
  p_camera[1] += x[4];
  p_camera[2] += x[5];
}

/// Field of one view, ready for the cost functions. The ceres interpolator serves the Jet
/// path (the autodiff reference of the tests); evaluate() uses the field's own one-pass
/// bicubic, the same interpolant.
struct SmoothView {
  using Interpolator = ceres::BiCubicInterpolator<EdgeDistanceField::Grid>;
  SmoothView(const std::vector<Eigen::Vector2d>& edges, const EdgeFieldOptions& o)
      : field(edges, o), grid(field.grid()), interpolator(grid) {}
  SmoothView(const SmoothView&) = delete;  // the interpolator refers to this grid
  SmoothView& operator=(const SmoothView&) = delete;
  /// Offset f (edge -> pixel) at (u, v) and, when J is given, df/d(u, v) (row-major 2x2):
  /// bicubic (value and exact gradient) in the band, the nearest-edge form outside it.
  inline void evaluate(double u, double v, double f[2], double J[4]) const __attribute__((always_inline));

  EdgeDistanceField field;
  EdgeDistanceField::Grid grid;  // the interpolator keeps a reference to it
  Interpolator interpolator;
};

// Inline, and forced so (always_inline at its declaration): it runs once per point per pass,
// a call through the shared library's PLT cannot be inlined into the pass, and with the
// bicubic inlined into it GCC's heuristics would keep it a call.
inline void SmoothView::evaluate(double u, double v, double f[2], double J[4]) const {
  if (field.in_band(u, v)) {
    if (J == nullptr) {
      field.interpolate(u, v, f, nullptr, nullptr);
      return;
    }
    double df_du[2], df_dv[2];
    field.interpolate(u, v, f, df_du, df_dv);
    J[0] = df_du[0];
    J[1] = df_dv[0];
    J[2] = df_du[1];
    J[3] = df_dv[1];
    return;
  }
  Eigen::Vector2d p, n;
  field.nearest_edge({u, v}, &p, &n);
  const double du = u - p.x(), dv = v - p.y();
  if (n.squaredNorm() > 0.5) {
    // f = n n^T (uv - p): the offset to the edge's tangent line.
    const double along = du * n.x() + dv * n.y();
    f[0] = along * n.x();
    f[1] = along * n.y();
    if (J != nullptr) {
      J[0] = n.x() * n.x();
      J[1] = J[2] = n.x() * n.y();
      J[3] = n.y() * n.y();
    }
  } else {
    f[0] = du;
    f[1] = dv;
    if (J != nullptr) {
      J[0] = J[3] = 1.0;
      J[1] = J[2] = 0.0;
    }
  }
}

/// The residual of one point as a template, so that Jets can differentiate it (the
/// reference the analytic Jacobian of ViewEdgeCost is tested against).
template <typename T>
void smooth_edge_residual(const ProjectionModel& cam, const SmoothView& view, const T* p_camera,
                          T* residual) {
  T uv[2];
  project_total(cam, p_camera, uv);
  const EdgeDistanceField& f = view.field;
  const double u = value_of(uv[0]), v = value_of(uv[1]);
  if (f.in_band(u, v)) {
    view.interpolator.Evaluate(uv[1], uv[0], residual);
    return;
  }
  Eigen::Vector2d p, n;
  f.nearest_edge({u, v}, &p, &n);
  const T du = uv[0] - T(p.x()), dv = uv[1] - T(p.y());
  if (n.squaredNorm() > 0.5) {
    const T along = du * T(n.x()) + dv * T(n.y());
    residual[0] = along * T(n.x());
    residual[1] = along * T(n.y());
  } else {
    residual[0] = du;
    residual[1] = dv;
  }
}

/// Huber folded into a 2-vector residual: r' = r sqrt(rho(s) / s), s = |r|^2, so that
/// |r'|^2 = rho(s), the objective of a per-point ceres::HuberLoss.
template <typename T>
void apply_huber(double huber_px, T* r) {
  if (huber_px <= 0.0) return;
  using std::sqrt;
  const T s = r[0] * r[0] + r[1] * r[1];
  const double delta2 = huber_px * huber_px;
  if (value_of(s) <= delta2) return;
  // rho(s) = 2 delta sqrt(s) - delta^2 beyond delta^2.
  const T norm = sqrt(s);
  const T scale = sqrt((T(2.0 * huber_px) * norm - T(delta2)) / s);
  r[0] *= scale;
  r[1] *= scale;
}

/// Normal equations of Eq. (2) at one pose, accumulated point by point (no N x 6 Jacobian
/// is stored): what a Gauss-Newton / Levenberg-Marquardt step needs, plus the J^T J of the
/// Huber-free residuals for the covariance, from the same pass.
struct NormalEquations {
  core::Matrix6d JtJ = core::Matrix6d::Zero();  ///< J^T J of the (Huber-folded) residuals
  core::Vector6d Jtr = core::Vector6d::Zero();  ///< J^T r
  double r2 = 0.0;                              ///< |r|^2 (twice the cost)
  /// sum over the points beyond the Huber width of (J_f^T J_f - J_r^T J_r), J_f the
  /// Jacobian without Huber: JtJ + huber_excess is J^T J of the plain residuals.
  core::Matrix6d huber_excess = core::Matrix6d::Zero();
  core::Matrix6d JtJ_plain() const { return JtJ + huber_excess; }
  NormalEquations& operator+=(const NormalEquations& o) {
    JtJ += o.JtJ;
    Jtr += o.Jtr;
    r2 += o.r2;
    huber_excess += o.huber_excess;
    return *this;
  }
};

/// Fit of one view's points at a pose: the Huber-free point-to-edge distances (+infinity
/// for points not in front of the camera) and how many project into the image.
struct PointFit {
  std::vector<double> distances_px;
  int in_image = 0;
};

/// Each point of one view at one pose, Huber-free: its pixel (uv, 2n, NaN for points not in
/// front of the camera), residual (r, 2n) and Jacobian (J, row-major 2n x 6). What the
/// covariance reads of the view (covariance_input.hpp).
struct PointJacobians {
  std::vector<double> uv, r, J;
};

/// All points of one view in one cost function (Ceres' per-block overhead dominates with
/// one block per point), parameter block [rx ry rz tx ty tz] (angle-axis, metres).
/// Analytic Jacobian: d(residual)/d(x) = d(huber)/d(r) * d(field)/d(uv) * d(uv)/d(p_camera)
/// * d(p_camera)/d(x); the rotation's derivatives are computed once per evaluation.
class ViewEdgeCost : public ceres::CostFunction {
 public:
  /// The pointees must outlive the cost function.
  ViewEdgeCost(const ProjectionModel* cam, const SmoothView* view,
               const std::vector<Eigen::Vector3d>* points, double huber_px);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  /// Evaluate() at pose x, plus each point's pixel (2n, NaN for points not in front of the
  /// camera) when uv is not null. jacobian (row-major 2n x 6) may be null.
  void evaluate_points(const double* x, double* uv, double* residuals, double* jacobian) const;
  /// The normal equations of this view's residuals at x added to *ne (skipped when ne is
  /// null), and the fit of its points (Huber-free distances, points in the image) in *fit,
  /// in one pass: one Levenberg-Marquardt evaluation that also yields the per-view fit and
  /// the covariance's J^T J at the pose where the solve stops. With ne and points given, the
  /// pass also records every point's Huber-free residual and Jacobian in *points (the
  /// covariance's input, so that it needs no pass of its own at the solution).
  void accumulate(const double* x, NormalEquations* ne, PointFit* fit,
                  PointJacobians* points = nullptr) const;
  int num_points() const { return static_cast<int>(points_->size()); }

 private:
  /// Calls sink(i, eval) for every point at pose x, with its Jacobian when with_jacobian.
  template <typename Sink>
  void for_each_point(const double* x, bool with_jacobian, Sink&& sink) const;

  const ProjectionModel* cam_;
  const SmoothView* view_;
  const std::vector<Eigen::Vector3d>* points_;
  double huber_px_;
};

}  // namespace rgbdt::extrinsics::detail
