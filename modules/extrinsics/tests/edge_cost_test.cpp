// The analytic Jacobian of our Eq. (2) cost (src/edge_cost.cpp) against automatic
// differentiation of the same residual (Jets through the angle-axis rotation, the total
// projection, the field and the Huber fold), at poses that exercise every branch: bicubic
// band, nearest-edge form, Huber active, depth clamp.
#include "../src/edge_cost.hpp"

#include <gtest/gtest.h>

#include <random>

#include "rgbdt/extrinsics/edge_alignment.hpp"

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

using Jet6 = ceres::Jet<double, 6>;

struct Counts {
  int in_band = 0, outside = 0, huber = 0, clamped = 0;
};

// Compares ViewEdgeCost with autodiff at x for every point of the view; counts which
// branches the points took.
void expect_same_jacobian(const detail::ProjectionModel& cam, const detail::SmoothView& view,
                          const std::vector<Eigen::Vector3d>& points, double huber_px,
                          const core::Vector6d& x, Counts* counts_out) {
  const detail::ViewEdgeCost cost(&cam, &view, &points, huber_px);
  const size_t n = points.size();
  std::vector<double> r(2 * n), J(12 * n), r_only(2 * n);
  const double* parameters[] = {x.data()};
  double* jacobians[] = {J.data()};
  EXPECT_TRUE(cost.Evaluate(parameters, r.data(), jacobians));
  EXPECT_TRUE(cost.Evaluate(parameters, r_only.data(), nullptr));
  Counts& counts = *counts_out;
  Jet6 xj[6];
  for (int k = 0; k < 6; ++k) xj[k] = Jet6(x[k], k);
  for (size_t i = 0; i < n; ++i) {
    Jet6 pc[3], ref[2];
    detail::transform_point(xj, points[i], pc);
    detail::smooth_edge_residual(cam, view, pc, ref);
    const double f2 = ref[0].a * ref[0].a + ref[1].a * ref[1].a;
    detail::apply_huber(huber_px, ref);
    double uv[2];
    const double pcd[3] = {pc[0].a, pc[1].a, pc[2].a};
    detail::project_total(cam, pcd, uv);
    counts.in_band += view.field.in_band(uv[0], uv[1]);
    counts.outside += !view.field.in_band(uv[0], uv[1]);
    counts.huber += huber_px > 0.0 && f2 > huber_px * huber_px;
    counts.clamped += pcd[2] < detail::kMinDepthM;
    for (int j = 0; j < 2; ++j) {
      // Both evaluate the same expressions in another order (rotation matrix vs
      // AngleAxisRotatePoint): agreement to rounding, ~1e-12 relative.
      const double scale = 1.0 + std::abs(ref[j].a);
      ASSERT_NEAR(r[2 * i + j], ref[j].a, 1e-9 * scale) << "point " << i;
      ASSERT_NEAR(r_only[2 * i + j], ref[j].a, 1e-9 * scale) << "point " << i;
      for (int k = 0; k < 6; ++k) {
        ASSERT_NEAR(J[12 * i + 6 * j + k], ref[j].v[k], 1e-7 * (1.0 + std::abs(ref[j].v[k])))
            << "point " << i << ", residual " << j << ", parameter " << k;
      }
    }
  }
}

core::CameraIntrinsics equidistant_intrinsics() {
  core::CameraIntrinsics in = testing::table1_intrinsics();
  in.model = core::DistortionModel::kEquidistant;
  in.distortion = {0.05, -0.01, 0.002, -0.0005};
  return in;
}

struct Scene {
  explicit Scene(const core::CameraIntrinsics& in = testing::table1_intrinsics(true)) : camera(in) {}
  core::PinholeCamera camera;
  Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  std::vector<TargetView> views = testing::make_views(camera, truth, testing::table1_placements());
  detail::ProjectionModel cam = detail::make_projection_model(camera);
};

TEST(ViewEdgeCost, AnalyticJacobianEqualsAutodiffInEveryBranch) {
  // Plumb-bob (closed-form projection Jacobian) and equidistant (Jets) cameras.
  for (const auto& intrinsics : {testing::table1_intrinsics(true), equidistant_intrinsics()}) {
    SCOPED_TRACE(core::to_string(intrinsics.model));
    const Scene s(intrinsics);
    Counts total;
    // Near the truth (band), a few degrees and centimetres off (band edge, Huber), 30 deg
    // off (nearest-edge form far away), and the LIDAR pushed behind the camera (depth clamp).
    const std::vector<Eigen::Isometry3d> poses = {
        s.truth, testing::offset_guess(s.truth, 0.3, -0.2, 0.1, 0.003, 0, 0.002),
        testing::offset_guess(s.truth, 3, 0, 2, 0.05, 0, 0),
        testing::offset_guess(s.truth, 30, 0, 0, 0, 0, 0),
        testing::offset_guess(s.truth, 0, 0, 0, 7.0, 0, 0)};
    for (const double huber_px : {0.0, 2.0}) {
      for (size_t v = 0; v < s.views.size(); v += 3) {
        const detail::SmoothView view(s.views[v].image_edge_points_px, {});
        for (const auto& T : poses) {
          expect_same_jacobian(s.cam, view, s.views[v].lidar_circle_points, huber_px,
                               core::to_vector6(T), &total);
          if (HasFatalFailure()) return;
        }
      }
    }
    // Every branch was taken by many points.
    EXPECT_GT(total.in_band, 100);
    EXPECT_GT(total.outside, 100);
    EXPECT_GT(total.huber, 100);
    EXPECT_GT(total.clamped, 100);
  }
}

TEST(ViewEdgeCost, AccumulatedNormalEquationsEqualTheStackedJacobians) {
  // accumulate() sums J^T J, J^T r and |r|^2 point by point (the LM polish never stores J);
  // they must equal the products of the Jacobians evaluate_points() returns, with Huber
  // (what LM solves) and without (the covariance's JtJ_plain), and the fit must be the
  // Huber-free distances and the in-image count of core::PinholeCamera.
  const Scene s;
  const detail::SmoothView view(s.views[2].image_edge_points_px, {});
  const auto& points = s.views[2].lidar_circle_points;
  const size_t n = points.size();
  int total_huber_active = 0;
  // At the truth (all in the band), a few degrees off (Huber active for many points) and
  // far off (nearest-edge form, points behind the camera).
  for (const auto& T : {s.truth, testing::offset_guess(s.truth, 3, 0, 2, 0.05, 0, 0),
                        testing::offset_guess(s.truth, 0, 0, 0, 7.0, 0, 0)}) {
    const core::Vector6d x = core::to_vector6(T);
    detail::NormalEquations ne;
    detail::PointFit fit;
    detail::ViewEdgeCost(&s.cam, &view, &points, 2.0).accumulate(x.data(), &ne, &fit);
    using RowMajorJ = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>;
    RowMajorJ J(2 * n, 6), J_plain(2 * n, 6);
    Eigen::VectorXd r(2 * n), f(2 * n), uv(2 * n);
    detail::ViewEdgeCost(&s.cam, &view, &points, 2.0).evaluate_points(x.data(), nullptr, r.data(), J.data());
    detail::ViewEdgeCost(&s.cam, &view, &points, 0.0).evaluate_points(x.data(), uv.data(), f.data(),
                                                                       J_plain.data());
    const core::Matrix6d JtJ = J.transpose() * J, JtJ_plain = J_plain.transpose() * J_plain;
    const core::Vector6d Jtr = J.transpose() * r;
    // Same sums in another order (per point vs. blocked gemm): rounding, ~1e-15 relative
    // to the largest term; 1e-9 of the scale leaves room for cancellation in off-diagonals.
    const double scale = JtJ.cwiseAbs().maxCoeff();
    EXPECT_LT((ne.JtJ - JtJ).cwiseAbs().maxCoeff(), 1e-9 * scale);
    EXPECT_LT((ne.JtJ_plain() - JtJ_plain).cwiseAbs().maxCoeff(), 1e-9 * JtJ_plain.cwiseAbs().maxCoeff());
    EXPECT_LT((ne.Jtr - Jtr).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + Jtr.cwiseAbs().maxCoeff()));
    EXPECT_NEAR(ne.r2, r.squaredNorm(), 1e-12 * (1.0 + r.squaredNorm()));
    int in_image = 0, huber_active = 0;
    ASSERT_EQ(fit.distances_px.size(), n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d px(uv[2 * i], uv[2 * i + 1]);
      if (!px.allFinite()) {
        EXPECT_TRUE(std::isinf(fit.distances_px[i])) << "point " << i;
        continue;
      }
      in_image += s.camera.in_image(px);
      const double d = std::hypot(f[2 * i], f[2 * i + 1]);
      huber_active += d > 2.0;
      EXPECT_NEAR(fit.distances_px[i], d, 1e-12 * (1.0 + d)) << "point " << i;
    }
    EXPECT_EQ(fit.in_image, in_image);
    total_huber_active += huber_active;
    // Without normal equations, only the fit (projection without its Jacobian: rounding).
    detail::PointFit fit_only;
    detail::ViewEdgeCost(&s.cam, &view, &points, 2.0).accumulate(x.data(), nullptr, &fit_only);
    ASSERT_EQ(fit_only.distances_px.size(), n);
    for (size_t i = 0; i < n; ++i) {
      const double d = fit.distances_px[i];
      if (std::isinf(d)) EXPECT_EQ(fit_only.distances_px[i], d);
      else EXPECT_NEAR(fit_only.distances_px[i], d, 1e-9 * (1.0 + d)) << "point " << i;
    }
    EXPECT_EQ(fit_only.in_image, fit.in_image);
  }
  EXPECT_GT(total_huber_active, 100);  // the Huber correction was exercised
}

TEST(EdgeDistanceField, InterpolateEqualsCeresBiCubicInterpolator) {
  // The field's one-pass bicubic must be ceres::BiCubicInterpolator's interpolant over the
  // same grid, value and gradient, at every in-band pixel (tile borders included).
  const Scene s;
  const EdgeDistanceField field(s.views[0].image_edge_points_px);
  const EdgeDistanceField::Grid grid = field.grid();
  const ceres::BiCubicInterpolator<EdgeDistanceField::Grid> ceres_interpolator(grid);
  std::mt19937 rng(5);
  const auto& edges = s.views[0].image_edge_points_px;
  std::uniform_int_distribution<size_t> pick(0, edges.size() - 1);
  std::uniform_real_distribution<double> offset(-4.0, 4.0);  // [px], around the band
  int checked = 0;
  for (int i = 0; i < 200000 && checked < 5000; ++i) {
    const Eigen::Vector2d& e = edges[pick(rng)];
    const double u = e.x() + offset(rng), v = e.y() + offset(rng);
    if (!field.in_band(u, v)) continue;
    double f[2], df_du[2], df_dv[2], g[2], dg_dv[2], dg_du[2];
    field.interpolate(u, v, f, df_du, df_dv);
    ceres_interpolator.Evaluate(v, u, g, dg_dv, dg_du);
    for (int k = 0; k < 2; ++k) {
      // Same sums in another order: rounding only.
      ASSERT_NEAR(f[k], g[k], 1e-12) << u << ", " << v;
      ASSERT_NEAR(df_du[k], dg_du[k], 1e-12) << u << ", " << v;
      ASSERT_NEAR(df_dv[k], dg_dv[k], 1e-12) << u << ", " << v;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 5000);
}

TEST(ViewEdgeCost, AlignEdgesCovarianceEqualsCeresCovariance) {
  // align_edges forms the jacobian term (J^T J)^-1 sigma^2 of its covariance itself;
  // ceres::Covariance (dense SVD) on the same residuals at the same pose must give the same
  // matrix. (The total adds the LIDAR circle terms, which Ceres cannot see.) With its
  // default step tolerance the solve takes a last step shorter than 0.05 sigma without a
  // pass, and the covariance is the last pass's; with none, it is at the pose reported.
  Scene s;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.3);  // [px], so that sigma^2 is not ~0
  for (auto& v : s.views)
    for (auto& p : v.image_edge_points_px) p += Eigen::Vector2d(noise(rng), noise(rng));
  EdgeAlignmentOptions every_step;
  every_step.step_tolerance_sigma = 0.0;
  const EdgeAlignmentResult r = align_edges(s.views, s.camera, every_step);
  ASSERT_TRUE(r.covariance_valid) << r.message;
  // That short step changes the Jacobian term by far less than a covariance's own
  // precision (a few percent from ~3000 points): 1e-3 relative.
  const EdgeAlignmentResult fast = align_edges(s.views, s.camera);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      EXPECT_NEAR(fast.covariance_terms.jacobian(i, j), r.covariance_terms.jacobian(i, j),
                  1e-3 * std::sqrt(r.covariance_terms.jacobian(i, i) * r.covariance_terms.jacobian(j, j)))
          << "entry " << i << ", " << j;
  core::Vector6d x = core::to_vector6(r.T_camera_lidar);
  std::vector<std::unique_ptr<detail::SmoothView>> fields;
  ceres::Problem problem;
  size_t count = 0;
  for (const auto& v : s.views) {
    fields.push_back(std::make_unique<detail::SmoothView>(v.image_edge_points_px, EdgeFieldOptions{}));
    problem.AddResidualBlock(
        new detail::ViewEdgeCost(&s.cam, fields.back().get(), &v.lidar_circle_points, 0.0), nullptr,
        x.data());
    count += v.lidar_circle_points.size();
  }
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::DENSE_SVD;
  options.null_space_rank = -1;
  ceres::Covariance covariance(options);
  const std::vector<std::pair<const double*, const double*>> blocks = {{x.data(), x.data()}};
  ASSERT_TRUE(covariance.Compute(blocks, &problem));
  core::Matrix6d expected;
  covariance.GetCovarianceBlock(x.data(), x.data(), expected.data());
  expected *= r.rms_px * r.rms_px * count / static_cast<double>(count - 6);
  // The pose goes through Isometry3d and back (~1e-16) and the two inversions differ by
  // rounding; 1e-6 relative is far below any use of a covariance.
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      EXPECT_NEAR(r.covariance_terms.jacobian(i, j), expected(i, j),
                  1e-6 * std::sqrt(expected(i, i) * expected(j, j)))
          << "entry " << i << ", " << j;
}

}  // namespace
}  // namespace rgbdt::extrinsics
