#include "rgbdt/extrinsics/edge_alignment.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

constexpr double kDeg = M_PI / 180.0;

struct Scene {
  core::PinholeCamera camera{testing::table1_intrinsics(true)};
  Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  std::vector<TargetView> views = testing::make_views(camera, truth, testing::table1_placements());
};

// Noiseless data (image edges = projected circles): the minimum of Eq. (2) is the truth, so
// the only error left is the field's (tangent-line and float storage, < 0.01 px), i.e.
// micro-degrees and micrometres at 3-6 m. The limits are the targets.
constexpr double kNoiselessRotDeg = 0.01;
constexpr double kNoiselessTransM = 1e-4;

class RecoversFromTable1Offsets : public ::testing::TestWithParam<std::array<double, 6>> {};

TEST_P(RecoversFromTable1Offsets, OursConvergesToTheTruth) {
  const Scene s;
  const auto o = GetParam();
  const Eigen::Isometry3d guess = testing::offset_guess(s.truth, o[0], o[1], o[2], o[3], o[4], o[5]);
  const EdgeAlignmentResult r = align_edges(s.views, s.camera, {}, guess);
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_FALSE(r.initial_from_closed_form);
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), kNoiselessRotDeg * kDeg);
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), kNoiselessTransM);
  EXPECT_LT(r.rms_px, 0.05);
  EXPECT_TRUE(r.outlier_views().empty()) << r.message;
}

// A few rows of Table 1 (rotation, translation, mixed) and one beyond it.
INSTANTIATE_TEST_SUITE_P(EdgeAlignment, RecoversFromTable1Offsets,
                         ::testing::Values(std::array<double, 6>{15, 0, 0, 0, 0, 0},
                                           std::array<double, 6>{0, 15, 5, 0, 0, 0},
                                           std::array<double, 6>{0, 0, 0, 1, 1.25, 1.25},
                                           std::array<double, 6>{20, -20, 20, 2, -2, 2}));

TEST(EdgeAlignment, NeedsNoInitialGuess) {
  const Scene s;
  const EdgeAlignmentResult r = align_edges(s.views, s.camera);
  EXPECT_TRUE(r.initial_from_closed_form);
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), kNoiselessRotDeg * kDeg) << r.message;
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), kNoiselessTransM) << r.message;
}

TEST(EdgeAlignment, SeveralHolesPerViewShareOneField) {
  // Multi-hole boards: each view's field holds the edges of all its holes, so a circle
  // point is pulled to whichever image hole is nearest. Two views of four circles each.
  const Scene s;
  std::vector<TargetView> merged(2);
  for (size_t i = 0; i < s.views.size(); ++i) {
    TargetView& m = merged[i / 4];
    const TargetView& v = s.views[i];
    m.name = "board " + std::to_string(i / 4);
    m.radius_m = v.radius_m;
    m.image_width = v.image_width;
    m.image_height = v.image_height;
    auto append = [](auto& to, const auto& from) { to.insert(to.end(), from.begin(), from.end()); };
    append(m.lidar_circle_points, v.lidar_circle_points);
    append(m.image_edge_points_px, v.image_edge_points_px);
    append(m.lidar_centers, v.lidar_centers);
    append(m.lidar_normals, v.lidar_normals);
    append(m.image_ellipses, v.image_ellipses);
  }
  const EdgeAlignmentResult r = align_edges(merged, s.camera);
  EXPECT_TRUE(r.initial_from_closed_form);
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), kNoiselessRotDeg * kDeg) << r.message;
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), kNoiselessTransM) << r.message;
}

TEST(EdgeAlignment, PaperMethodConvergesToTable1Accuracy) {
  const Scene s;
  EdgeAlignmentOptions options;
  options.method = EdgeAlignmentMethod::kPaperPlaneFit;
  options.compute_covariance = false;
  const EdgeAlignmentResult r =
      align_edges(s.views, s.camera, options, testing::offset_guess(s.truth, 5, 0, 0, 0, 0, 0));
  // Table 1 of the paper reports errors up to 0.37 deg and 3.5 cm for its method (pixel
  // distance transform, plane-fit gradients); allow the same order.
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), 1.0 * kDeg) << r.message;
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), 0.10) << r.message;
}

TEST(EdgeAlignment, NoisyEdgesGiveAnHonestCovariance) {
  Scene s;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.3);  // [px], a good sub-pixel detector
  for (auto& v : s.views)
    for (auto& p : v.image_edge_points_px) p += Eigen::Vector2d(noise(rng), noise(rng));
  const EdgeAlignmentResult r = align_edges(s.views, s.camera);
  ASSERT_TRUE(r.covariance_valid);
  // 0.3 px on 2880 points: the estimate stays within ~0.05 deg / 5 mm.
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), 0.05 * kDeg);
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), 0.005);
  EXPECT_NEAR(r.rms_px, 0.3, 0.1);  // the residual is the edge noise
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eig(r.covariance);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
  // The translation sigma must not claim more than the error it made by a large factor: the
  // error is within 6 sigma of the covariance (points are correlated, so sigma is optimistic).
  const Eigen::Vector3d dt = r.T_camera_lidar.translation() - s.truth.translation();
  const double mahalanobis2 = dt.transpose() * r.covariance.bottomRightCorner<3, 3>().inverse() * dt;
  EXPECT_LT(std::sqrt(mahalanobis2), 6.0);
}

TEST(EdgeAlignment, StepToleranceStopsOnlyWhereTheRestIsFarBelowOneSigma) {
  // The polish stops once its next step is < step_tolerance_sigma standard deviations; run to
  // the relative-step tolerance instead, the pose may move by at most about that much.
  for (const double noise_px : {0.0, 0.3}) {
    Scene s;
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, noise_px > 0.0 ? noise_px : 1.0);
    if (noise_px > 0.0)
      for (auto& v : s.views)
        for (auto& p : v.image_edge_points_px) p += Eigen::Vector2d(noise(rng), noise(rng));
    EdgeAlignmentOptions full;
    full.step_tolerance_sigma = 0.0;
    const EdgeAlignmentResult early = align_edges(s.views, s.camera);
    const EdgeAlignmentResult late = align_edges(s.views, s.camera, full);
    ASSERT_TRUE(early.converged && late.converged) << early.message << " / " << late.message;
    ASSERT_TRUE(early.covariance_valid);
    EXPECT_LT(early.iterations, late.iterations);  // the tolerance did stop the polish early
    const core::Vector6d dx = core::to_vector6(late.T_camera_lidar) - core::to_vector6(early.T_camera_lidar);
    const double sigmas = std::sqrt(dx.dot(early.covariance.inverse() * dx));
    // The skipped steps shrink at least linearly, so the rest is a small multiple of the
    // last step (< 0.01 sigma); 0.05 sigma leaves room for that and is still nothing
    // measurable.
    EXPECT_LT(sigmas, 0.05) << "noise " << noise_px << " px";
    EXPECT_NEAR(early.rms_px, late.rms_px, 1e-6 * (1.0 + late.rms_px));
  }
  EdgeAlignmentOptions bad;
  bad.step_tolerance_sigma = -1.0;
  EXPECT_NE(bad.validate().find("step_tolerance_sigma"), std::string::npos);
}

TEST(EdgeAlignment, RejectsAViewWhoseImageEdgesDoNotMatchAndSaysWhy) {
  Scene s;
  // A ninth view whose image edges belong to another placement (a mismatched image).
  TargetView bad = s.views[2];
  bad.name = "mismatched view";
  bad.image_edge_points_px = s.views[5].image_edge_points_px;
  bad.image_ellipses = s.views[5].image_ellipses;
  s.views.push_back(bad);
  const EdgeAlignmentResult r =
      align_edges(s.views, s.camera, {}, testing::offset_guess(s.truth, 3, 0, 3, 0.1, 0, 0));
  ASSERT_EQ(r.outlier_views(), std::vector<int>{8}) << r.message;
  EXPECT_FALSE(r.views[8].used);
  EXPECT_NE(r.views[8].reason.find("do not match"), std::string::npos) << r.views[8].reason;
  EXPECT_NE(r.message.find("mismatched view"), std::string::npos) << r.message;
  // Once the view is out, the others give the noiseless answer.
  EXPECT_LT(core::rotation_error_rad(r.T_camera_lidar, s.truth), kNoiselessRotDeg * kDeg);
  EXPECT_LT(core::translation_error_m(r.T_camera_lidar, s.truth), kNoiselessTransM);
}

TEST(EdgeAlignment, ThrowsWhenNoViewIsUsable) {
  Scene s;
  for (auto& v : s.views) v.image_edge_points_px.clear();
  s.views[0].lidar_circle_points.clear();
  try {
    align_edges(s.views, s.camera);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no usable view"), std::string::npos) << what;
    EXPECT_NE(what.find("view 0: no LIDAR circle points"), std::string::npos) << what;
    EXPECT_NE(what.find("view 1: only 0 image edge points"), std::string::npos) << what;
  }
  EXPECT_THROW(align_edges({}, s.camera), std::invalid_argument);
}

TEST(EdgeAlignment, ValidatesOptionsAndMethodNames) {
  EdgeAlignmentOptions o;
  EXPECT_EQ(o.validate(), "");
  o.max_iterations = 0;
  EXPECT_NE(o.validate().find("max_iterations"), std::string::npos);
  EXPECT_EQ(edge_alignment_method_from_string("paper"), EdgeAlignmentMethod::kPaperPlaneFit);
  EXPECT_EQ(to_string(EdgeAlignmentMethod::kSmoothField), "edge");
  EXPECT_THROW(edge_alignment_method_from_string("mi"), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::extrinsics
