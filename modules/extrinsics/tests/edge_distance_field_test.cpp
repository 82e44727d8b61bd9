#include "rgbdt/extrinsics/edge_distance_field.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace rgbdt::extrinsics {
namespace {

std::vector<Eigen::Vector2d> circle_points(const Eigen::Vector2d& c, double r, int n) {
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < n; ++i) {
    const double t = 2.0 * M_PI * i / n;
    pts.emplace_back(c.x() + r * std::cos(t), c.y() + r * std::sin(t));
  }
  return pts;
}

TEST(EdgeDistanceField, MatchesDistanceToTheTrueCircleNearAndFar) {
  const Eigen::Vector2d c(400.3, 300.7);
  const double r = 80.0;
  // 360 points: 1.4 px spacing, like a projected LIDAR circle at ~5 m.
  const EdgeDistanceField field(circle_points(c, r, 360));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(0, 2 * M_PI), radial(-8.0, 8.0), far(-300, 300);
  double worst_near = 0.0;
  for (int i = 0; i < 2000; ++i) {
    const double t = angle(rng), dr = radial(rng);
    const Eigen::Vector2d px = c + (r + dr) * Eigen::Vector2d(std::cos(t), std::sin(t));
    worst_near = std::max(worst_near, std::abs(field.distance_px(px) - std::abs(dr)));
  }
  // Tangent-line distance vs the arc: spacing^2 / (8 r) = 0.003 px, plus the float grid and
  // bicubic error; 0.01 px is 100x below the paper's 1 px distance transform.
  EXPECT_LT(worst_near, 0.01);
  double worst_far = 0.0;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Vector2d px = c + Eigen::Vector2d(far(rng), far(rng));
    const double truth = std::abs((px - c).norm() - r);
    if (truth < 10.0) continue;
    worst_far = std::max(worst_far, std::abs(field.distance_px(px) - truth));
  }
  // Far away the exact nearest point is used; the tangent line at the nearest sample differs
  // from the arc by at most spacing^2 / (8 r) plus the sampling phase of the point.
  EXPECT_LT(worst_far, 0.05);
}

TEST(EdgeDistanceField, OffsetIsLinearAcrossTheEdgeSoItsZeroIsUnbiased) {
  // A straight edge at a sub-pixel position: the interpolated offset vanishes exactly on it.
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < 200; ++i) pts.emplace_back(100.0 + 0.7 * i, 250.37);
  const EdgeDistanceField field(pts);
  for (double v : {250.37, 251.0, 249.2}) {
    const Eigen::Vector2d o = field.offset({160.25, v});
    EXPECT_NEAR(o.y(), v - 250.37, 1e-4) << "v = " << v;  // float storage ~1e-5 px
    EXPECT_NEAR(o.x(), 0.0, 1e-4);
  }
}

TEST(EdgeDistanceField, RejectsEmptyAndNonFiniteInput) {
  EXPECT_THROW(EdgeDistanceField({}), std::invalid_argument);
  EXPECT_THROW(EdgeDistanceField({Eigen::Vector2d(1, NAN)}), std::invalid_argument);
  EdgeFieldOptions bad;
  bad.band_px = 1.0;
  EXPECT_NE(bad.validate(), "");
  EXPECT_THROW(EdgeDistanceField({Eigen::Vector2d(1, 1)}, bad), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::extrinsics
