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

}  // namespace rgbdt::extrinsics::detail
