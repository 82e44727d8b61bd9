#include "rgbdt/extrinsics/initial_guess.hpp"

#include <gtest/gtest.h>

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

constexpr double kDeg = M_PI / 180.0;

TEST(InitialGuess, AlignRigidRecoversAKnownTransform) {
  const Eigen::Isometry3d T = core::make_transform(core::rotation_from_rpy(0.3, -0.2, 1.1),
                                                   Eigen::Vector3d(0.5, -1.0, 2.0));
  std::vector<Eigen::Vector3d> a = {{1, 0, 0}, {0, 2, 0}, {0, 0, 3}, {1, 1, 1}}, b;
  for (const auto& p : a) b.push_back(T * p);
  const Eigen::Isometry3d est = align_rigid(a, b);
  EXPECT_LT(core::rotation_error_rad(est, T), 1e-9);
  EXPECT_LT(core::translation_error_m(est, T), 1e-9);
}

TEST(InitialGuess, CircleFromEllipseRecoversCentreAndOneOfTheNormals) {
  const core::PinholeCamera camera(testing::table1_intrinsics(true));
  // Board 4 m ahead, tilted 35 degrees about the camera's y axis.
  const Eigen::Vector3d center(0.4, -0.2, 4.0);
  const Eigen::Vector3d normal = Eigen::AngleAxisd(35 * kDeg, Eigen::Vector3d::UnitY()) *
                                 Eigen::Vector3d(0, 0, -1);
  const Eigen::Vector3d e1 = normal.cross(Eigen::Vector3d::UnitX()).normalized();
  const Eigen::Vector3d e2 = normal.cross(e1);
  std::vector<cv::Point2f> px;
  for (int i = 0; i < 360; ++i) {
    const double t = i * kDeg;
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.project(center + 0.3 * (std::cos(t) * e1 + std::sin(t) * e2), &uv));
    px.emplace_back(uv.x(), uv.y());
  }
  const CircleInCamera c = circle_from_ellipse(cv::fitEllipse(px), 0.3, camera);
  // The ellipse centre is not the projected circle centre and the major axis is only nearly
  // parallel to the image: a first-order estimate, good to ~2% of the range and a few
  // degrees, which is all the refinement needs.
  EXPECT_LT((c.center - center).norm(), 0.02 * center.norm());
  const double best = std::min(std::acos(std::clamp(c.normals[0].dot(normal), -1.0, 1.0)),
                               std::acos(std::clamp(c.normals[1].dot(normal), -1.0, 1.0)));
  EXPECT_LT(best, 3.0 * kDeg);
  EXPECT_THROW(circle_from_ellipse(cv::RotatedRect({10, 10}, {0, 0}, 0), 0.3, camera),
               std::invalid_argument);
}

TEST(InitialGuess, ClosedFormIsNearTheTruthWithoutAnyGuess) {
  const core::PinholeCamera camera(testing::table1_intrinsics(true));
  const Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  const auto views = testing::make_views(camera, truth, testing::table1_placements());
  const InitialGuessResult g = closed_form_initial_guess(views, camera);
  ASSERT_TRUE(g.ok) << g.message;
  EXPECT_EQ(g.num_correspondences, 8);
  // PnP on ellipse centres: the ellipse centre is a few px off the projected circle centre,
  // i.e. ~0.5 degree / a few cm; the edge alignment then removes this bias.
  EXPECT_LT(core::rotation_error_rad(g.T_camera_lidar, truth), 1.0 * kDeg) << g.message;
  EXPECT_LT(core::translation_error_m(g.T_camera_lidar, truth), 0.10) << g.message;
}

TEST(InitialGuess, ThreeViewsGiveAGuessThroughTheEllipsePoses) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  auto placements = testing::table1_placements();
  placements.resize(3);
  const auto views = testing::make_views(camera, truth, placements);
  const InitialGuessResult g = closed_form_initial_guess(views, camera);
  ASSERT_TRUE(g.ok) << g.message;
  EXPECT_NE(g.message.find("ellipse poses"), std::string::npos) << g.message;
  // Three circles: the pose comes from ellipse centres/normals (first-order); within a few
  // degrees and ~10 cm, inside the basin shown by the Table 1 benchmark.
  EXPECT_LT(core::rotation_error_rad(g.T_camera_lidar, truth), 5.0 * kDeg) << g.message;
  EXPECT_LT(core::translation_error_m(g.T_camera_lidar, truth), 0.25) << g.message;
}

TEST(InitialGuess, OneCircleIsNotEnoughAndSaysWhy) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  auto placements = testing::table1_placements();
  placements.resize(1);
  const auto views = testing::make_views(camera, testing::true_T_camera_lidar(), placements);
  const InitialGuessResult g = closed_form_initial_guess(views, camera);
  EXPECT_FALSE(g.ok);
  EXPECT_NE(g.message.find("at least 2 holes"), std::string::npos) << g.message;
}

}  // namespace
}  // namespace rgbdt::extrinsics
