#pragma once
// Projection used inside the cost functions: core::project_generic's model, made total so
// that the solver can start far from the solution.
#include <ceres/jet.h>

#include <algorithm>
#include <cmath>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::extrinsics::detail {

struct ProjectionModel {
  core::DistortionModel model = core::DistortionModel::kNone;
  double k[4] = {0, 0, 0, 0};  // fx fy cx cy
  double d[5] = {0, 0, 0, 0, 0};
  double r_max = 1e6;          // normalised radius beyond which distortion is not trusted
  int width = 0, height = 0;
};

ProjectionModel make_projection_model(const core::PinholeCamera& camera);

/// Points closer than this are projected as if at this depth [m]: behind-camera points at a
/// poor initial guess then still have a finite residual that pulls them forward.
constexpr double kMinDepthM = 0.05;

/// Like core::project_generic, but total: depth clamped to kMinDepthM, and beyond r_max
/// (where polynomial distortion folds back) the distortion at r_max is scaled radially, so
/// the projection stays continuous and monotonic.
template <typename T>
void project_total(const ProjectionModel& cam, const T* p, T* uv) {
  using std::sqrt;
  T z = p[2];
  if (z < T(kMinDepthM)) z = T(kMinDepthM);
  T x = p[0] / z;
  T y = p[1] / z;
  const T r2 = x * x + y * y;
  T scale(1.0);
  if (r2 > T(cam.r_max * cam.r_max)) {
    scale = sqrt(r2) / T(cam.r_max);
    x /= scale;
    y /= scale;
  }
  T d[5];
  for (int i = 0; i < 5; ++i) d[i] = T(cam.d[i]);
  T xd, yd;
  core::distort_generic(cam.model, d, x, y, &xd, &yd);
  uv[0] = T(cam.k[0]) * (xd * scale) + T(cam.k[2]);
  uv[1] = T(cam.k[1]) * (yd * scale) + T(cam.k[3]);
}

/// project_total and its Jacobian d(uv)/d(p) (row-major 2x3). Closed form for the
/// pinhole and plumb_bob models inside r_max (the cost functions' common case), Jets over
/// the normalised coordinates otherwise.
inline void project_total_with_jacobian(const ProjectionModel& cam, const double* p, double* uv,
                                        double* J) {
  const bool clamped = p[2] < kMinDepthM;
  const double inv_z = 1.0 / (clamped ? kMinDepthM : p[2]);
  const double x = p[0] * inv_z, y = p[1] * inv_z;
  const double r2 = x * x + y * y;
  double xd, yd, J_d[4];  // distorted normalised point and d(xd, yd)/d(x, y), row-major
  if (r2 <= cam.r_max * cam.r_max && cam.model != core::DistortionModel::kEquidistant) {
    if (cam.model == core::DistortionModel::kPlumbBob) {
      // plumb_bob: xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2), yd = y radial + p1 (r2 + 2 y^2)
      // + 2 p2 x y, radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3 (d = k1 k2 p1 p2 k3).
      const double* d = cam.d;
      const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
      const double dradial_dr2 = d[0] + r2 * (2.0 * d[1] + 3.0 * r2 * d[4]);
      xd = x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
      yd = y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
      J_d[0] = radial + 2.0 * x * x * dradial_dr2 + 2.0 * d[2] * y + 6.0 * d[3] * x;
      J_d[1] = 2.0 * x * y * dradial_dr2 + 2.0 * d[2] * x + 2.0 * d[3] * y;
      J_d[2] = 2.0 * x * y * dradial_dr2 + 2.0 * d[2] * x + 2.0 * d[3] * y;
      J_d[3] = radial + 2.0 * y * y * dradial_dr2 + 6.0 * d[2] * y + 2.0 * d[3] * x;
    } else {
      xd = x;
      yd = y;
      J_d[0] = J_d[3] = 1.0;
      J_d[1] = J_d[2] = 0.0;
    }
  } else {
    // Equidistant, or beyond r_max: the same total projection of (x, y, 1) through Jets.
    using Jet2 = ceres::Jet<double, 2>;
    const Jet2 q[3] = {Jet2(x, 0), Jet2(y, 1), Jet2(1.0)};
    Jet2 uvj[2];
    project_total(cam, q, uvj);
    xd = (uvj[0].a - cam.k[2]) / cam.k[0];
    yd = (uvj[1].a - cam.k[3]) / cam.k[1];
    J_d[0] = uvj[0].v[0] / cam.k[0];
    J_d[1] = uvj[0].v[1] / cam.k[0];
    J_d[2] = uvj[1].v[0] / cam.k[1];
    J_d[3] = uvj[1].v[1] / cam.k[1];
  }
  uv[0] = cam.k[0] * xd + cam.k[2];
  uv[1] = cam.k[1] * yd + cam.k[3];
  // d(x, y)/d(p): perspective division; the clamped depth is a constant.
  const double dx_dz = clamped ? 0.0 : -x * inv_z, dy_dz = clamped ? 0.0 : -y * inv_z;
  for (int a = 0; a < 2; ++a) {
    const double j0 = cam.k[a] * J_d[2 * a], j1 = cam.k[a] * J_d[2 * a + 1];
    J[3 * a + 0] = j0 * inv_z;
    J[3 * a + 1] = j1 * inv_z;
    J[3 * a + 2] = j0 * dx_dz + j1 * dy_dz;
  }
}

}  // namespace rgbdt::extrinsics::detail
