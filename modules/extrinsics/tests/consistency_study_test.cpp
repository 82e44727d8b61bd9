// The covariance consistency study of issue #29 item 4, smaller: the first 16 cases of
// build/bin/calib_consistency (seeds 1-16: 1-10 views, 1- and 4-hole boards, range noise
// x0.5-2, the tilting LIDAR with and without its ring field, a 16-ring spinning one and a
// dense ring-less one, beam footprint and mixed pixels on), each calibrated and judged as
// rgbdt_calibrate does. The bench runs the full study.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "../bench/consistency_study.hpp"
#include "rgbdt/core/log.hpp"

namespace study = rgbdt::extrinsics::study;

TEST(ConsistencyStudy, DeliveredCovarianceContainsTheTruthAsOftenAsItSays) {
  rgbdt::core::set_log_level(rgbdt::core::LogLevel::kError);
  const std::filesystem::path tmp = std::filesystem::path(RGBDT_BINARY_DIR) / "test_tmp" / "consistency_study";
  std::vector<study::CaseResult> results;
  for (const study::Case& c : study::make_cases(16, 1)) {
    results.push_back(study::run_case(c, tmp));
    const study::CaseResult& r = results.back();
    std::printf("case %lu %s: %s NEES %.2f, %.3f deg / %.2f cm off, %s\n", static_cast<unsigned long>(c.seed),
                study::to_string(c.kind), r.ok ? "solved" : r.reason.c_str(), r.nees, r.err_rot_deg,
                r.err_trans_cm, r.verdict.c_str());
  }
  const study::Summary s = study::summarize(results);
  // Enough delivered cases for the statistics to mean something.
  ASSERT_GE(s.scored, 8) << s.cases_scored_total << " solved, " << s.failed << " FAILed";
  // A delivered estimate beyond its own 99.9 % ellipsoid is silently wrong.
  EXPECT_EQ(s.silently_wrong, 0);
  // With an honest covariance, each delivered case lies inside its 95 % ellipsoid with
  // probability 0.95: of 8-12 cases, fewer than 80 % inside has a probability below 2 %.
  EXPECT_GE(s.inside95, 0.8) << s.scored << " delivered";
  // Item 4 asks the mean NEES over >= 50 sessions to lie in [3, 9] (the bench's 128 give
  // 3.4-3.6: the covariance errs on the large side, by design where it takes the larger of
  // two estimates). Here n is about 11, so the sample mean scatters: a covariance scaled so
  // that the population mean sits at an edge m of the band gives NEES m / 6 chi-square(6),
  // whose mean over n cases has standard deviation (m / 6) sqrt(12 / n). The test fails
  // when the sample mean is 3 of those outside the band.
  const double n = s.scored;
  EXPECT_GE(s.mean_nees, 3.0 - 3.0 * (3.0 / 6.0) * std::sqrt(12.0 / n));
  EXPECT_LE(s.mean_nees, 9.0 + 3.0 * (9.0 / 6.0) * std::sqrt(12.0 / n));
}

// A study session (seed 4: five views of a 4-hole board, range noise x2, the tilting LIDAR
// with its ring field) whose polish meets the cost's roughness: many circle points project
// beyond the field's bicubic band, where the exact nearest-edge form switches from one edge
// point to the next, and LM's steps of a tenth of a sigma get rejected. A rejected step
// below 5 x step_tolerance_sigma ends the polish there (EdgeAlignmentOptions): it must save
// passes over damping and retrying, and leave the pose within 0.25 sigma (its threshold in
// the Jacobian term's sigma, the smaller) of where running to the relative-step tolerance
// ends.
TEST(ConsistencyStudy, ARejectedShortStepEndsThePolishNearTheMinimum) {
  rgbdt::core::set_log_level(rgbdt::core::LogLevel::kError);
  const std::filesystem::path tmp = std::filesystem::path(RGBDT_BINARY_DIR) / "test_tmp" / "consistency_rejected_step";
  const study::Case c = study::make_cases(4, 1).back();
  ASSERT_EQ(c.seed, 4u);
  rgbdt::extrinsics::EdgeAlignmentOptions options;
  const study::CaseViews cv = study::case_views(c, tmp, &options);
  ASSERT_GE(cv.views.size(), 3u);
  rgbdt::extrinsics::EdgeAlignmentOptions full = options;
  full.step_tolerance_sigma = 0.0;
  const auto early = rgbdt::extrinsics::align_edges(cv.views, cv.camera, options);
  const auto late = rgbdt::extrinsics::align_edges(cv.views, cv.camera, full);
  ASSERT_TRUE(early.converged && late.converged) << early.message << " / " << late.message;
  ASSERT_TRUE(early.covariance_valid) << early.message;
  // Accepted steps shrink 3x or more per iteration here, from about a sigma to the 0.05 that
  // ends a stage: 3-5 per stage (coarse and all points), one for the hole centres. Damping
  // after each rejection instead tries ~5 more steps per stage (21 iterations in all).
  EXPECT_LE(early.iterations, 12) << early.message;
  const rgbdt::core::Vector6d dx =
      rgbdt::core::to_vector6(late.T_camera_lidar) - rgbdt::core::to_vector6(early.T_camera_lidar);
  EXPECT_LT(std::sqrt(dx.dot(early.covariance_terms.jacobian.inverse() * dx)), 0.25);
}
