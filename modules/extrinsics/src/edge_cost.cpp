#include "edge_cost.hpp"

#include <cmath>
#include <limits>

namespace rgbdt::extrinsics::detail {

void SmoothView::evaluate(double u, double v, double f[2], double J[4]) const {
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

void ViewEdgeCost::evaluate_points(const double* x, double* uv_out, double* residuals,
                                   double* J, long jacobian_column_stride) const {
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

  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = (*points_)[i];
    const Eigen::Vector3d pc = R * p + t;
    double* r = residuals + 2 * i;
    double uv[2];
    Eigen::Matrix<double, 2, 3, Eigen::RowMajor> J_uv_pc;
    if (J == nullptr) project_total(*cam_, pc.data(), uv);
    else project_total_with_jacobian(*cam_, pc.data(), uv, J_uv_pc.data());
    if (uv_out != nullptr) {
      const bool in_front = pc.z() > kMinDepthM;
      uv_out[2 * i] = in_front ? uv[0] : std::numeric_limits<double>::quiet_NaN();
      uv_out[2 * i + 1] = in_front ? uv[1] : std::numeric_limits<double>::quiet_NaN();
    }
    if (J == nullptr) {
      view_->evaluate(uv[0], uv[1], r, nullptr);
      apply_huber(huber_px_, r);
      continue;
    }
    double J_f_uv[4];
    view_->evaluate(uv[0], uv[1], r, J_f_uv);
    Eigen::Matrix2d J_r_uv;
    J_r_uv << J_f_uv[0], J_f_uv[1], J_f_uv[2], J_f_uv[3];
    if (huber_px_ > 0.0) {
      const Eigen::Vector2d f(r[0], r[1]);
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
        r[0] = s * f.x();
        r[1] = s * f.y();
      }
    }
    const Eigen::Matrix<double, 2, 3> J_r_pc = J_r_uv * J_uv_pc;  // also d(r)/d(translation)
    if (jacobian_column_stride == 0) {
      double* row0 = J + 12 * i;
      double* row1 = row0 + 6;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d d = J_r_pc * (dR[k] * p);
        row0[k] = d.x();
        row1[k] = d.y();
        row0[3 + k] = J_r_pc(0, k);
        row1[3 + k] = J_r_pc(1, k);
      }
    } else {
      double* col = J + 2 * i;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d d = J_r_pc * (dR[k] * p);
        col[k * jacobian_column_stride] = d.x();
        col[k * jacobian_column_stride + 1] = d.y();
        col[(3 + k) * jacobian_column_stride] = J_r_pc(0, k);
        col[(3 + k) * jacobian_column_stride + 1] = J_r_pc(1, k);
      }
    }
  }
}

}  // namespace rgbdt::extrinsics::detail
