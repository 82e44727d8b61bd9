// The covariance of the extrinsics (covariance.hpp): its building blocks, and the
// systematic term's propagation and the few-view resampled term checked against Monte
// Carlo re-solves.
#include "rgbdt/extrinsics/covariance.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "synthetic_views.hpp"

namespace ext = rgbdt::extrinsics;
namespace t = rgbdt::extrinsics::testing;
using rgbdt::core::Matrix6d;
using rgbdt::core::Vector6d;

namespace {

/// A hole's LIDAR error: centre shift in the plane and along the normal [m], tilt [rad].
ext::LidarHoleSigma hole_sigma(double in_plane_m, double normal_m, double tilt_rad) {
  ext::LidarHoleSigma sigma;
  sigma.center_in_plane_m = in_plane_m;
  sigma.center_normal_m = normal_m;
  sigma.tilt_rad = tilt_rad;
  return sigma;
}

/// Moves each view's circle (points, centre, normal) by one draw of the hole error `sigma`
/// states, and gives align_edges that sigma for it.
void perturb_circles(std::vector<ext::TargetView>* views, const ext::LidarHoleSigma& sigma, std::mt19937* rng,
                     std::normal_distribution<double>* gauss, ext::EdgeAlignmentOptions* options) {
  auto g = [gauss](std::mt19937& r) { return (*gauss)(r); };
  for (auto& v : *views) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : v.lidar_circle_points) c += p;
    c /= static_cast<double>(v.lidar_circle_points.size());
    const Eigen::Vector3d n = (v.lidar_circle_points[0] - c).cross(v.lidar_circle_points[90] - c).normalized();
    const Eigen::Vector3d a1 = n.cross(Eigen::Vector3d::UnitZ()).normalized(), a2 = n.cross(a1);
    const Eigen::Vector3d shift =
        sigma.center_in_plane_m * (g(*rng) * a1 + g(*rng) * a2) + sigma.center_normal_m * g(*rng) * n;
    const Eigen::Matrix3d tilt =
        Eigen::AngleAxisd(sigma.tilt_rad * g(*rng), a1) * Eigen::AngleAxisd(sigma.tilt_rad * g(*rng), a2).toRotationMatrix();
    for (auto& p : v.lidar_circle_points) p = c + shift + tilt * (p - c);
    for (auto& lc : v.lidar_centers) lc = c + shift;
    for (auto& ln : v.lidar_normals) ln = tilt * ln;
    options->covariance_model.per_view.push_back({sigma});
  }
}

/// The Monte Carlo of the systematic term: `draws` re-solves from the truth, each on the
/// views' circles moved by one draw of a hole error (4 mm in the plane, 2 mm along the
/// normal, 10 mrad of tilt), with the propagated covariance alone (no jackknife). Returns
/// their mean NEES, each error taken in its estimate's chart (to_vector6, the chart the
/// covariance is in), and in *other_chart how many estimates lie in the other chart of the
/// truth's rotation vector (past a half turn from it).
double mean_nees_of_resolves(const rgbdt::core::PinholeCamera& camera, const Eigen::Isometry3d& truth,
                             const std::vector<t::Placement>& placements, int draws, int* other_chart) {
  const std::vector<ext::TargetView> clean = t::make_views(camera, truth, placements);
  const ext::LidarHoleSigma sigma = hole_sigma(0.004, 0.002, 0.01);
  std::mt19937 rng(11);
  std::normal_distribution<double> g;
  double sum_nees = 0.0;
  *other_chart = 0;
  for (int d = 0; d < draws; ++d) {
    std::vector<ext::TargetView> views = clean;
    ext::EdgeAlignmentOptions options;
    options.covariance_model.jackknife = false;  // the propagated term alone
    perturb_circles(&views, sigma, &rng, &g, &options);
    const ext::EdgeAlignmentResult r = ext::align_edges(views, camera, options, truth);
    EXPECT_TRUE(r.covariance_valid) << r.message;
    const Vector6d estimate = rgbdt::core::to_vector6(r.T_camera_lidar);
    *other_chart += (estimate - rgbdt::core::to_vector6(truth)).head<3>().norm() > 1.0 ? 1 : 0;
    sum_nees += ext::nees(estimate - rgbdt::core::to_vector6_near(truth, estimate), r.covariance);
  }
  return sum_nees / draws;
}

}  // namespace

TEST(Covariance, MaxIsAtLeastBothInEveryDirection) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  Matrix6d a, b;
  for (int i = 0; i < 36; ++i) {
    a(i / 6, i % 6) = g(rng);
    b(i / 6, i % 6) = g(rng);
  }
  const Matrix6d A = a * a.transpose(), B = b * b.transpose();
  const Matrix6d M = ext::covariance_max(A, B);
  for (int k = 0; k < 200; ++k) {
    Vector6d v;
    for (int i = 0; i < 6; ++i) v(i) = g(rng);
    const double m = v.dot(M * v);
    EXPECT_GE(m, v.dot(A * v) * (1 - 1e-12));
    EXPECT_GE(m, v.dot(B * v) * (1 - 1e-12));
  }
  EXPECT_LT((ext::covariance_max(A, 0.5 * A) - A).norm(), 1e-12 * A.norm());  // B <= A: A itself
}

TEST(Covariance, NeesOfAKnownCase) {
  Matrix6d C = Matrix6d::Zero();
  C.diagonal() << 1, 4, 9, 1, 1, 1;
  Vector6d e;
  e << 1, 2, 3, 0, 0, 0.5;
  EXPECT_NEAR(ext::nees(e, C), 3.25, 1e-12);
  EXPECT_TRUE(std::isinf(ext::nees(e, Matrix6d::Zero())));
}

// A hole of radius 0.3 m in a 1.2 m board, 36 edge points with 1 cm radial noise and 400
// board points with 1 cm noise along the normal: sigma_c = 1 cm sqrt(2 / 36) in the plane
// (sum u u^T = 18 I), 1 cm / sqrt(400) along the normal at the board's centre, and the
// slope's 1 cm / sqrt(sum u^2).
TEST(Covariance, LidarHoleSigmaFollowsTheNoise) {
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Vector3d c(5, 0.2, -0.1), n = Eigen::Vector3d(-1, 0.2, 0.1).normalized();
  const Eigen::Vector3d a1 = n.cross(Eigen::Vector3d::UnitZ()).normalized(), a2 = n.cross(a1);
  std::vector<Eigen::Vector3d> edges, board;
  for (int i = 0; i < 36; ++i) {
    const double th = 2 * M_PI * i / 36, r = 0.3 + noise(rng);
    edges.push_back(c + r * (std::cos(th) * a1 + std::sin(th) * a2));
  }
  double su2 = 0.0;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      const double u = -0.6 + 1.2 * (i + 0.5) / 20, w = -0.6 + 1.2 * (j + 0.5) / 20;
      board.push_back(c + u * a1 + w * a2 + noise(rng) * n);
      su2 += u * u;
    }
  }
  const ext::LidarHoleSigma s = ext::lidar_hole_sigma(edges, board, c, n, 0.3);
  // The noise estimates have 34 and 397 degrees of freedom: relative standard deviations
  // 12 % and 3.5 %; 35 % and 15 % are about 3 of them.
  EXPECT_NEAR(s.center_in_plane_m, 0.01 * std::sqrt(2.0 / 36.0), 0.35 * 0.01 * std::sqrt(2.0 / 36.0));
  EXPECT_NEAR(s.center_normal_m, 0.01 / 20.0, 0.15 * 0.01 / 20.0);
  EXPECT_NEAR(s.tilt_rad, 0.01 / std::sqrt(su2), 0.15 * 0.01 / std::sqrt(su2));
  EXPECT_THROW(ext::lidar_hole_sigma({c, c}, board, c, n, 0.3), std::invalid_argument);
  // The beam footprint widens the hole: edges 1.5 cm outside the nominal radius, all round,
  // leave the centre where it was and its uncertainty unchanged (not sqrt(1^2 + 1.5^2) cm).
  std::vector<Eigen::Vector3d> widened;
  for (const auto& p : edges) widened.push_back(c + (p - c) * (1.0 + 0.015 / (p - c).norm()));
  EXPECT_NEAR(ext::lidar_hole_sigma(widened, board, c, n, 0.3).center_in_plane_m, s.center_in_plane_m,
              0.01 * s.center_in_plane_m);
}

// An edge error that varies slowly around the hole (the point density of a scan pattern
// changing across it) moves the centre by its first Fourier order, which the circle fit
// absorbs; the white scatter of 180 edge points says nothing of it. Holes whose radial
// error has equal random amplitudes (1-sigma 3 mm) in orders 1-5 plus 1 mm of white noise:
// the centre's error per axis is the order-1 amplitude, and its mean square over the holes
// must match the reported in-plane sigma's square (ratio 1; 300 holes of 2 axes give a
// relative standard deviation of 6 %, so [0.7, 1.4] is 5 of them; the scatter term alone
// gives a ratio of 29).
TEST(Covariance, LidarHoleSigmaCoversASmoothEdgeError) {
  std::mt19937 rng(17);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector3d c(4, -0.3, 0.1), n = Eigen::Vector3d(-1, 0.1, 0.05).normalized();
  const Eigen::Vector3d a1 = n.cross(Eigen::Vector3d::UnitZ()).normalized(), a2 = n.cross(a1);
  std::vector<Eigen::Vector3d> board;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) board.push_back(c + (-0.6 + 0.06 * i) * a1 + (-0.6 + 0.06 * j) * a2);
  double ratio = 0.0;
  constexpr int kHoles = 300;
  for (int h = 0; h < kHoles; ++h) {
    Eigen::Matrix<double, 5, 2> amplitude;
    for (int k = 0; k < 5; ++k) amplitude.row(k) << 0.003 * g(rng), 0.003 * g(rng);
    std::vector<Eigen::Vector3d> edges;
    for (int i = 0; i < 180; ++i) {
      const double th = 2 * M_PI * (i + 0.5) / 180;
      double r = 0.3 + 0.001 * g(rng);
      for (int k = 0; k < 5; ++k) r += amplitude(k, 0) * std::cos((k + 1) * th) + amplitude(k, 1) * std::sin((k + 1) * th);
      edges.push_back(c + r * (std::cos(th) * a1 + std::sin(th) * a2));
    }
    // The fitted centre is off by the order-1 amplitudes; the sigma is computed about it.
    const Eigen::Vector3d fitted = c + amplitude(0, 0) * a1 + amplitude(0, 1) * a2;
    const ext::LidarHoleSigma s = ext::lidar_hole_sigma(edges, board, fitted, n, 0.3);
    ratio += amplitude.row(0).squaredNorm() / 2.0 / (s.center_in_plane_m * s.center_in_plane_m);
  }
  ratio /= kHoles;
  EXPECT_GT(ratio, 0.7);
  EXPECT_LT(ratio, 1.4);
}

// What the points' scatter cannot show. A beam footprint that measured an edge bias of 2 cm
// on a board seen at 30 deg incidence adds 0.5 * 2 cm * sin(30 deg) = 0.5 cm in the plane
// and along the normal; 360 edge points 1.75 mm apart on a 0.3 m hole count as one per
// 4 cm stretch of edge (twice the bias: 47 of them), not 360; and edges that happen to lie
// on the circle are still uncertain by the point spacing's quantisation (spacing / sqrt(12)).
TEST(Covariance, LidarHoleSigmaKeepsTheFootprintAndTheSpacing) {
  const Eigen::Vector3d n(-1, 0, 0);
  const double incidence = 30.0 * M_PI / 180.0;
  // The sensor at the origin sees the hole's centre 30 deg off the normal.
  const Eigen::Vector3d c = 5.0 * Eigen::Vector3d(std::cos(incidence), std::sin(incidence), 0.0);
  const Eigen::Vector3d a1(0, 1, 0), a2(0, 0, 1);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.005);
  std::vector<Eigen::Vector3d> edges, exact, board;
  for (int i = 0; i < 360; ++i) {
    const double th = 2 * M_PI * i / 360;
    edges.push_back(c + (0.3 + noise(rng)) * (std::cos(th) * a1 + std::sin(th) * a2));
    exact.push_back(c + 0.3 * (std::cos(th) * a1 + std::sin(th) * a2));
  }
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      board.push_back(c + (-0.6 + 0.06 * i) * a1 + (-0.6 + 0.06 * j) * a2);
    }
  }
  // Noise-free board: the normal's sigma is the footprint term alone.
  const ext::LidarHoleSigma fp = ext::lidar_hole_sigma(exact, board, c, n, 0.3, 0.02, 0.0);
  EXPECT_NEAR(fp.center_in_plane_m, 0.005, 1e-6);
  EXPECT_NEAR(fp.center_normal_m, 0.005, 1e-6);
  // Without a bias the same hole is judged by its scatter with all 360 points...
  const ext::LidarHoleSigma all = ext::lidar_hole_sigma(edges, board, c, n, 0.3, 0.0, 0.0);
  EXPECT_NEAR(all.center_in_plane_m, 0.005 * std::sqrt(2.0 / 360.0), 0.15 * 0.005 * std::sqrt(2.0 / 360.0));
  // ... with it, by 2 pi 0.3 / 0.04 = 47.1 independent stretches (and the footprint term).
  const ext::LidarHoleSigma capped = ext::lidar_hole_sigma(edges, board, c, n, 0.3, 0.02, 0.0);
  const double stretches = 2 * M_PI * 0.3 / 0.04;
  EXPECT_NEAR(capped.center_in_plane_m,
              std::sqrt(std::pow(all.center_in_plane_m, 2) * 360.0 / stretches + 0.005 * 0.005), 1e-6);
  // Exact edges 2 cm apart: spacing / sqrt(12) per point, 94 stretches of 2 cm.
  const ext::LidarHoleSigma quantised = ext::lidar_hole_sigma(exact, board, c, n, 0.3, 0.0, 0.02);
  EXPECT_NEAR(quantised.center_in_plane_m, 0.02 / std::sqrt(12.0) * std::sqrt(2.0 / (2 * M_PI * 0.3 / 0.02)), 1e-6);
}

// The systematic term is the linear propagation of the LIDAR circles' errors: perturb each
// view's circle (centre and tilt) by draws of the stated sigma, re-solve against the true
// image edges, and the solutions' NEES under the reported covariance must average 6.
TEST(Covariance, SystematicTermMatchesMonteCarloResolves) {
  const rgbdt::core::PinholeCamera camera(t::table1_intrinsics());
  const auto placements = t::table1_placements();
  constexpr int kDraws = 40;
  int other_chart = 0;
  const double mean_nees = mean_nees_of_resolves(camera, t::true_T_camera_lidar(),
                                                 {placements[0], placements[2], placements[5]}, kDraws, &other_chart);
  // Mean of 40 chi-square(6): mean 6, standard deviation sqrt(12 / 40) = 0.55; [4.3, 7.7]
  // is +-3 of them (the propagation is linear, the re-solves are not: a real mismatch of
  // the derivative shows as a factor, e.g. 4 for a missing rotation term).
  EXPECT_GT(mean_nees, 6.0 - 3 * 0.55);
  EXPECT_LT(mean_nees, 6.0 + 3 * 0.55);
  EXPECT_EQ(other_chart, 0);  // a rotation of about 120 deg: far from the half turn
}

// A LIDAR whose forward axis is its -y (as on the ART-BP rig) makes T_camera_lidar nearly a
// half turn: the solutions scatter to both sides of pi, and one that ends past pi is in the
// other chart of the rotation vector, where the directions across the axis point the
// opposite way. The covariance must be that of the chart the YAML writes (to_vector6): the
// experiment above on this rig, each error taken in its estimate's chart, averages NEES 6.
TEST(Covariance, HoldsInTheWrittenChartNearAHalfTurn) {
  const rgbdt::core::PinholeCamera camera(t::table1_intrinsics());
  // true_T_camera_lidar()'s LIDAR frame turned by 90 deg about its z axis: then the rotation
  // is a half turn about (0, 1, -1) / sqrt(2); 1 mrad short of it here.
  const Eigen::Matrix3d quarter = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Isometry3d truth = rgbdt::core::make_transform(
      Eigen::AngleAxisd(M_PI - 0.001, Eigen::Vector3d(0, 1, -1).normalized()).toRotationMatrix(),
      t::true_T_camera_lidar().translation());
  std::vector<t::Placement> placements;
  for (int i : {0, 2, 5}) {
    t::Placement p = t::table1_placements()[static_cast<size_t>(i)];
    p.center_lidar = quarter.transpose() * p.center_lidar;
    placements.push_back(p);
  }
  constexpr int kDraws = 40;
  int past_pi = 0;
  const double mean_nees = mean_nees_of_resolves(camera, truth, placements, kDraws, &past_pi);
  std::printf("%d of %d solutions past pi, mean NEES %.2f\n", past_pi, kDraws, mean_nees);
  // The case must happen: the rotation about the axis scatters by a few mrad, so a good
  // share of the solutions end past pi.
  EXPECT_GE(past_pi, 5);
  // As above: mean of 40 chi-square(6), 6 +- 3 x 0.55.
  EXPECT_GT(mean_nees, 6.0 - 3 * 0.55);
  EXPECT_LT(mean_nees, 6.0 + 3 * 0.55);
}

// The same experiment with two nearly frontal single-hole views 0.6 m apart and 3 cm circle
// errors in the plane, as a 16-ring LIDAR gives them: the rotation about the line between
// the two holes rests on their normals alone, and a centre error moves the pose along a
// curve. The first-order term is then too small; the resampled term, which raises the
// total below 3 views, must bring the mean NEES of the re-solves down to a chi-square's.
TEST(Covariance, FewViewsAreCoveredByTheResampledTerm) {
  const rgbdt::core::PinholeCamera camera(t::table1_intrinsics());
  const Eigen::Isometry3d truth = t::true_T_camera_lidar();
  const std::vector<t::Placement> placements = {{{5.0, -0.3, 0.1}, 3, -2}, {{5.8, 0.3, 0.0}, -2, 3}};
  const std::vector<ext::TargetView> clean = t::make_views(camera, truth, placements);
  const ext::LidarHoleSigma sigma = hole_sigma(0.03, 0.004, 0.002);
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  constexpr int kDraws = 30;
  double nees_resampled = 0.0, nees_linear = 0.0;
  int inside95 = 0;
  for (int d = 0; d < kDraws; ++d) {
    std::vector<ext::TargetView> views = clean;
    ext::EdgeAlignmentOptions options;
    perturb_circles(&views, sigma, &rng, &g, &options);
    const ext::EdgeAlignmentResult r = ext::align_edges(views, camera, options, truth);
    ASSERT_TRUE(r.covariance_valid) << r.message;
    ASSERT_TRUE(r.covariance_terms.resampled_used);
    const Vector6d e = rgbdt::core::to_vector6(r.T_camera_lidar) - rgbdt::core::to_vector6(truth);
    const double n = ext::nees(e, r.covariance);
    nees_resampled += n;
    inside95 += n <= 12.59 ? 1 : 0;  // chi-square(6) 95 % quantile
    nees_linear += ext::nees(e, r.covariance_terms.sandwich + r.covariance_terms.systematic);
  }
  // The linear term alone is over-confident here beyond item 4's bound on the mean NEES (9;
  // measured 14.8), which is why the resampled term exists (a model that made this case
  // linear would fail this line, and the test would need another case).
  EXPECT_GT(nees_linear / kDraws, 9.0);
  // Mean of 30 chi-square(6): 6 +- sqrt(12 / 30) = 0.63; the resampled term estimates the
  // spread from 64 draws (about +-18 %), so the upper bound is 3 sigma above that margin.
  EXPECT_LT(nees_resampled / kDraws, 1.18 * 6.0 + 3 * 0.63);
  EXPECT_GE(inside95, 25);  // 95 % of 30 is 28.5; 25 is 3 binomial sigma (1.2) below
}
