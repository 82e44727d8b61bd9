#include "rgbdt/extrinsics/verdict.hpp"

#include <gtest/gtest.h>

#include <random>

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

bool has_reason(const CalibrationVerdict& v, VerdictLevel level, const std::string& text) {
  for (const auto& r : v.reasons)
    if (r.level == level && r.text.find(text) != std::string::npos) return true;
  return false;
}

/// The views of Table 1's placements with the noise of a real pair of sensors: 0.3 px on
/// the image edges (a good sub-pixel detector) and a 5 mm placement error per LIDAR circle
/// (each view's circle shifted as a whole, as a hole-centre fit error shifts it).
std::vector<TargetView> noisy_views(const core::PinholeCamera& camera, const std::vector<testing::Placement>& placements,
                                    unsigned seed) {
  auto views = testing::make_views(camera, testing::true_T_camera_lidar(), placements);
  std::mt19937 rng(seed);
  std::normal_distribution<double> edge(0.0, 0.3), circle(0.0, 0.005);
  for (auto& v : views) {
    for (auto& p : v.image_edge_points_px) p += Eigen::Vector2d(edge(rng), edge(rng));
    const Eigen::Vector3d shift(circle(rng), circle(rng), circle(rng));
    for (auto& p : v.lidar_circle_points) p += shift;
    for (auto& c : v.lidar_centers) c += shift;
  }
  return views;
}

TEST(Verdict, ConsistentViewsPass) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, testing::table1_placements(), 1);
  // The covariance is told the circles' true uncertainty (5 mm per axis, no tilt), as the
  // app tells it each hole's from its detection.
  VerdictOptions o;
  o.alignment.covariance_model.per_view.assign(views.size(), {LidarHoleSigma{0.005, 0.005, 0.0}});
  const EdgeAlignmentResult r = align_edges(views, camera, o.alignment);
  const CalibrationVerdict v = judge_calibration(views, camera, r, o);
  EXPECT_EQ(v.level, VerdictLevel::kPass) << v.summary();
  EXPECT_EQ(v.used_views, 8);
  // The numbers behind the PASS: the residual is within the expected noise (0.3 px edges,
  // 5 mm circles at 3-6 m under fx 1335: 1.1-2.2 px; expected with 1 cm: 2.2-4.5 px).
  EXPECT_LT(v.rms_px, v.expected_rms_px);
  ASSERT_GE(v.reprojection_px, 0.0);
  EXPECT_LT(v.reprojection_px, v.expected_reprojection_px);
  // Leave-one-view-out was run and, the views being consistent, stays far inside the bound
  // of disagreement and names no view.
  EXPECT_GE(v.lovo_max_translation_cm, 0.0);
  EXPECT_LT(v.lovo_max_translation_cm, 0.5 * o.lovo_fail_cm);
  EXPECT_LT(v.lovo_max_rotation_deg, 0.5 * o.lovo_fail_deg);
  for (const auto& vv : v.views) EXPECT_FALSE(vv.lovo_influential) << vv.name;
  EXPECT_NE(format_verdict_report(v).find("**Verdict: PASS**"), std::string::npos);
}

// Leave-one-view-out judges a move by its bounds and by the uncertainty of the estimate
// without the view. The consistent views of Table 1 move it by ~0.1 deg and ~0.5 cm; with
// bounds far below that, every move is "beyond the bounds": within the uncertainty the
// circles' 5 mm give, that is a WARN (the views agree, loosely); with the circles claimed
// 100x more certain than they are, the same moves are beyond it and FAIL.
TEST(Verdict, LeaveOneViewOutFailsOnlyBeyondTheUncertaintyToo) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, testing::table1_placements(), 1);
  VerdictOptions o;
  o.lovo_fail_deg = 1e-4;
  o.lovo_fail_cm = 1e-3;
  o.alignment.covariance_model.per_view.assign(views.size(), {LidarHoleSigma{0.005, 0.005, 0.0}});
  const EdgeAlignmentResult r = align_edges(views, camera, o.alignment);
  const CalibrationVerdict loose = judge_calibration(views, camera, r, o);
  EXPECT_EQ(loose.level, VerdictLevel::kWarn) << loose.summary();
  EXPECT_TRUE(has_reason(loose, VerdictLevel::kWarn, "the views agree, but each pins the transform only loosely"))
      << loose.summary();
  EXPECT_GT(loose.lovo_max_translation_cm, o.lovo_fail_cm);

  o.alignment.covariance_model.per_view.assign(views.size(), {LidarHoleSigma{0.00005, 0.00005, 0.0}});
  const EdgeAlignmentResult r_tight = align_edges(views, camera, o.alignment);
  const CalibrationVerdict tight = judge_calibration(views, camera, r_tight, o);
  EXPECT_EQ(tight.level, VerdictLevel::kFail) << tight.summary();
  EXPECT_TRUE(has_reason(tight, VerdictLevel::kFail, "the views disagree")) << tight.summary();
}

// The LIDAR and image detectors each order a multi-hole board's holes from their own
// viewpoint; the hole-centre check pairs them by position, not by index. Two-hole views
// (Table 1's placements in pairs) with the image ellipses listed in reverse order.
TEST(Verdict, HoleCentresArePairedWhateverTheDetectorsOrder) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto singles = noisy_views(camera, testing::table1_placements(), 4);
  std::vector<TargetView> views;
  for (size_t k = 0; k + 1 < singles.size(); k += 2) {
    TargetView v = singles[k];
    const TargetView& w = singles[k + 1];
    v.lidar_circle_points.insert(v.lidar_circle_points.end(), w.lidar_circle_points.begin(), w.lidar_circle_points.end());
    v.image_edge_points_px.insert(v.image_edge_points_px.end(), w.image_edge_points_px.begin(), w.image_edge_points_px.end());
    v.lidar_centers.push_back(w.lidar_centers[0]);
    v.lidar_normals.push_back(w.lidar_normals[0]);
    v.image_ellipses.insert(v.image_ellipses.begin(), w.image_ellipses[0]);  // reversed
    views.push_back(std::move(v));
  }
  VerdictOptions o;
  o.alignment.covariance_model.per_view.assign(views.size(), std::vector<LidarHoleSigma>(2, {0.005, 0.005, 0.0}));
  const EdgeAlignmentResult r = align_edges(views, camera, o.alignment, testing::true_T_camera_lidar());
  const CalibrationVerdict v = judge_calibration(views, camera, r, o);
  ASSERT_GE(v.reprojection_px, 0.0);
  // Paired by index the holes are boards apart (hundreds of px).
  EXPECT_LT(v.reprojection_px, v.expected_reprojection_px) << v.summary();
  EXPECT_NE(v.level, VerdictLevel::kFail) << v.summary();
}

TEST(Verdict, OneViewWarnsAndNamesTheWeakDirection) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, {testing::table1_placements()[2]}, 2);
  // One hole gives no closed-form guess: start 1 deg and 2 cm off.
  const EdgeAlignmentResult r = align_edges(
      views, camera, {}, testing::offset_guess(testing::true_T_camera_lidar(), 1, 1, 1, 0.02, 0.02, 0.02));
  const CalibrationVerdict v = judge_calibration(views, camera, r);
  EXPECT_EQ(v.level, VerdictLevel::kWarn) << v.summary();
  EXPECT_TRUE(has_reason(v, VerdictLevel::kWarn, "one view: " + v.weakest_direction + " is weakly constrained"))
      << v.summary();
  EXPECT_NE(v.weakest_direction.find("the "), std::string::npos) << v.weakest_direction;
  EXPECT_GT(v.weakest_sigma_m, v.strongest_sigma_m);
}

// Every view's image belongs to another placement: no transform fits them all.
TEST(Verdict, ImagesOfOtherViewsFail) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  auto views = noisy_views(camera, testing::table1_placements(), 3);
  const auto original = views;
  for (size_t k = 0; k < views.size(); ++k) {
    const auto& other = original[(k + 3) % views.size()];
    views[k].image_edge_points_px = other.image_edge_points_px;
    views[k].image_ellipses = other.image_ellipses;
  }
  const EdgeAlignmentResult r = align_edges(views, camera);
  const CalibrationVerdict v = judge_calibration(views, camera, r);
  EXPECT_EQ(v.level, VerdictLevel::kFail) << v.summary();
  EXPECT_NE(v.summary().find("FAIL: "), std::string::npos);
}

TEST(Verdict, TranslationBeyondTheBoundFailsAndNamesTheValue) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, testing::table1_placements(), 4);
  const EdgeAlignmentResult r = align_edges(views, camera);
  VerdictOptions o;
  o.max_translation_m = 0.05;  // the true |t| is 0.13 m
  const CalibrationVerdict v = judge_calibration(views, camera, r, o);
  EXPECT_EQ(v.level, VerdictLevel::kFail) << v.summary();
  EXPECT_TRUE(has_reason(v, VerdictLevel::kFail, "exceeds the maximum of 0.050 m")) << v.summary();
}

// One view's image edges shifted by 12 px: the solver rejects it, the verdict warns by name.
TEST(Verdict, ARejectedViewWarnsByName) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  auto views = noisy_views(camera, testing::table1_placements(), 5);
  for (auto& p : views[4].image_edge_points_px) p.x() += 12.0;
  const EdgeAlignmentResult r = align_edges(views, camera);
  const CalibrationVerdict v = judge_calibration(views, camera, r);
  EXPECT_EQ(v.level, VerdictLevel::kWarn) << v.summary();
  EXPECT_TRUE(has_reason(v, VerdictLevel::kWarn, "view 4 was rejected by the solver")) << v.summary();
  EXPECT_FALSE(v.views[4].used);
}

// An estimate that puts the board behind the camera fails whatever its residual.
TEST(Verdict, BoardBehindTheCameraFails) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, testing::table1_placements(), 6);
  EdgeAlignmentResult r = align_edges(views, camera);
  r.T_camera_lidar = core::make_transform(core::rotation_from_rpy(0, M_PI, 0), Eigen::Vector3d::Zero()) *
                     r.T_camera_lidar;
  const CalibrationVerdict v = judge_calibration(views, camera, r);
  EXPECT_EQ(v.level, VerdictLevel::kFail);
  EXPECT_TRUE(has_reason(v, VerdictLevel::kFail, "view 0: the board is behind the camera")) << v.summary();
}

TEST(Verdict, RejectsInvalidOptionsAndMismatchedResults) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const auto views = noisy_views(camera, testing::table1_placements(), 7);
  const EdgeAlignmentResult r = align_edges(views, camera);
  VerdictOptions o;
  o.max_translation_m = -1;
  EXPECT_THROW(judge_calibration(views, camera, r, o), std::invalid_argument);
  const std::vector<TargetView> fewer(views.begin(), views.begin() + 3);
  EXPECT_THROW(judge_calibration(fewer, camera, r), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::extrinsics
