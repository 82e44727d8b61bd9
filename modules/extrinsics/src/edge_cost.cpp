#include "edge_cost.hpp"

#include <cmath>
#include <limits>

namespace rgbdt::extrinsics::detail {

ViewEdgeCost::ViewEdgeCost(const ProjectionModel* cam, const SmoothView* view,
                           const std::vector<Eigen::Vector3d>* points, double huber_px)
    : cam_(cam), view_(view), points_(points), huber_px_(huber_px) {
  set_num_residuals(2 * static_cast<int>(points->size()));
  mutable_parameter_block_sizes()->push_back(6);
}

bool ViewEdgeCost::Evaluate(double const* const* parameters, double* residuals,
                            double** jacobians) const {
  evaluate_points(parameters[0], nullptr, residuals, jacobians != nullptr ? jacobians[0] : nullptr);
  return true;
}

namespace {

/// One point at one pose, as for_each_point hands it on.
struct PointEval {
  double uv[2];        // projection [px]
  bool in_front;       // deeper than kMinDepthM (else the depth was clamped)
  double f[2];         // Huber-free offset, edge -> projection [px]
  double r[2];         // residual: f with the Huber loss folded in
  bool huber_active;   // |f| beyond the Huber width, so r != f
  Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J;        // dr/dx (when asked)
  Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J_plain;  // df/dx, only when huber_active
};

}  // namespace

template <typename Sink>
void ViewEdgeCost::for_each_point(const double* x, bool with_jacobian, Sink&& sink) const {
  const size_t n = points_->size();
  // R and dR/dx[k] once per evaluation (Jets over the three rotation parameters only).
  using Jet3 = ceres::Jet<double, 3>;
  const Jet3 aa[3] = {Jet3(x[0], 0), Jet3(x[1], 1), Jet3(x[2], 2)};
  Jet3 Rj[9];
  ceres::AngleAxisToRotationMatrix(aa, ceres::RowMajorAdapter3x3(Rj));
  Eigen::Matrix3d R, dR[3];
  for (int a = 0; a < 9; ++a) {
    R(a / 3, a % 3) = Rj[a].a;
    for (int k = 0; k < 3; ++k) dR[k](a / 3, a % 3) = Rj[a].v[k];
  }
  const Eigen::Vector3d t(x[3], x[4], x[5]);

  PointEval e;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = (*points_)[i];
    const Eigen::Vector3d pc = R * p + t;
    e.in_front = pc.z() > kMinDepthM;
    e.huber_active = false;
    if (!with_jacobian) {
      project_total(*cam_, pc.data(), e.uv);
      view_->evaluate(e.uv[0], e.uv[1], e.f, nullptr);
      e.r[0] = e.f[0];
      e.r[1] = e.f[1];
      apply_huber(huber_px_, e.r);
      e.huber_active = e.r[0] != e.f[0] || e.r[1] != e.f[1];
      sink(i, e);
      continue;
    }
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J_uv_pc;
    project_total_with_jacobian(*cam_, pc.data(), e.uv, J_uv_pc.data());
    Eigen::Matrix<double, 2, 2, Eigen::RowMajor> J_f_uv;
    view_->evaluate(e.uv[0], e.uv[1], e.f, J_f_uv.data());
    e.r[0] = e.f[0];
    e.r[1] = e.f[1];
    Eigen::Matrix2d J_r_uv = J_f_uv;
    if (huber_px_ > 0.0) {
      const Eigen::Vector2d f(e.f[0], e.f[1]);
      const double a2 = f.squaredNorm(), delta = huber_px_;
      if (a2 > delta * delta) {
        // r' = s(a) f with a = |f|, s = sqrt(2 delta / a - delta^2 / a^2):
        // dr'/df = s I + f (ds/da f / a)^T, ds/da = delta (delta - a) / (a^3 s).
        const double a = std::sqrt(a2);
        const double s = std::sqrt(2.0 * delta / a - delta * delta / a2);
        const double ds_da = delta * (delta - a) / (a2 * a * s);
        const Eigen::Matrix2d J_huber =
            s * Eigen::Matrix2d::Identity() + (ds_da / a) * f * f.transpose();
        J_r_uv = J_huber * J_r_uv;
        e.r[0] = s * f.x();
        e.r[1] = s * f.y();
        e.huber_active = true;
      }
    }
    // d(p_camera)/d(rotation) = [dR[0] p, dR[1] p, dR[2] p]; d(p_camera)/d(translation) = I.
    Eigen::Matrix3d dpc_drot;
    for (int k = 0; k < 3; ++k) dpc_drot.col(k) = dR[k] * p;
    const Eigen::Matrix<double, 2, 3> J_r_pc = J_r_uv * J_uv_pc;
    e.J.leftCols<3>() = J_r_pc * dpc_drot;
    e.J.rightCols<3>() = J_r_pc;
    if (e.huber_active) {
      const Eigen::Matrix<double, 2, 3> J_f_pc = J_f_uv * J_uv_pc;
      e.J_plain.leftCols<3>() = J_f_pc * dpc_drot;
      e.J_plain.rightCols<3>() = J_f_pc;
    }
    sink(i, e);
  }
}

void ViewEdgeCost::evaluate_points(const double* x, double* uv_out, double* residuals,
                                   double* J) const {
  for_each_point(x, J != nullptr, [&](size_t i, const PointEval& e) {
    if (uv_out != nullptr) {
      uv_out[2 * i] = e.in_front ? e.uv[0] : std::numeric_limits<double>::quiet_NaN();
      uv_out[2 * i + 1] = e.in_front ? e.uv[1] : std::numeric_limits<double>::quiet_NaN();
    }
    residuals[2 * i] = e.r[0];
    residuals[2 * i + 1] = e.r[1];
    if (J != nullptr) Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>>(J + 12 * i) = e.J;
  });
}

void ViewEdgeCost::accumulate(const double* x, NormalEquations* ne, PointFit* fit,
                              PointJacobians* points) const {
  fit->distances_px.resize(points_->size());
  fit->in_image = 0;
  if (ne == nullptr) points = nullptr;  // no Jacobians in a residual-only pass
  if (points != nullptr) {
    points->uv.resize(2 * points_->size());
    points->r.resize(2 * points_->size());
    points->J.resize(12 * points_->size());
  }
  // Sums in locals (registers), added to *ne once.
  core::Matrix6d JtJ = core::Matrix6d::Zero(), huber_excess = core::Matrix6d::Zero();
  core::Vector6d Jtr = core::Vector6d::Zero();
  double r2 = 0.0;
  // The image covers [-0.5, size - 0.5) (core::PinholeCamera::in_image).
  const double u_end = cam_->width - 0.5, v_end = cam_->height - 0.5;
  // Inlined, so that each point's PointEval stays in registers instead of passing through
  // memory to a call per point.
  for_each_point(x, ne != nullptr, [&](size_t i, const PointEval& e) __attribute__((always_inline)) {
    const bool finite = e.in_front && std::isfinite(e.uv[0]) && std::isfinite(e.uv[1]);
    fit->distances_px[i] = finite ? std::sqrt(e.f[0] * e.f[0] + e.f[1] * e.f[1])
                                  : std::numeric_limits<double>::infinity();
    fit->in_image += finite && e.uv[0] >= -0.5 && e.uv[1] >= -0.5 && e.uv[0] < u_end && e.uv[1] < v_end;
    if (ne == nullptr) return;
    if (points != nullptr) {
      // As evaluate_points() with no Huber loss: the plain offset and its Jacobian.
      points->uv[2 * i] = e.in_front ? e.uv[0] : std::numeric_limits<double>::quiet_NaN();
      points->uv[2 * i + 1] = e.in_front ? e.uv[1] : std::numeric_limits<double>::quiet_NaN();
      points->r[2 * i] = e.f[0];
      points->r[2 * i + 1] = e.f[1];
      Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>>(points->J.data() + 12 * i) =
          e.huber_active ? e.J_plain : e.J;
    }
    // Upper triangles only (mirrored below): 21 of the 36 entries.
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) JtJ(a, b) += e.J(0, a) * e.J(0, b) + e.J(1, a) * e.J(1, b);
      Jtr(a) += e.J(0, a) * e.r[0] + e.J(1, a) * e.r[1];
    }
    r2 += e.r[0] * e.r[0] + e.r[1] * e.r[1];
    if (e.huber_active) {
      for (int a = 0; a < 6; ++a) {
        for (int b = a; b < 6; ++b) {
          huber_excess(a, b) += e.J_plain(0, a) * e.J_plain(0, b) + e.J_plain(1, a) * e.J_plain(1, b) -
                                e.J(0, a) * e.J(0, b) - e.J(1, a) * e.J(1, b);
        }
      }
    }
  });
  if (ne == nullptr) return;
  for (int a = 0; a < 6; ++a) {
    for (int b = 0; b < a; ++b) {
      JtJ(a, b) = JtJ(b, a);
      huber_excess(a, b) = huber_excess(b, a);
    }
  }
  ne->JtJ += JtJ;
  ne->Jtr += Jtr;
  ne->r2 += r2;
  ne->huber_excess += huber_excess;
}

}  // namespace rgbdt::extrinsics::detail
