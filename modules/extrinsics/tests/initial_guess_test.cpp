#include "rgbdt/extrinsics/initial_guess.hpp"

#include <gtest/gtest.h>

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// Views of a board with four holes (0.5 x 0.4 m apart, r 0.12 m) at the given placements,
/// the LIDAR holes listed row by row from the board's top-left; the image ellipses in the
/// order `ellipse_order[view]` gives (the image detector's own order), from the true pose.
std::vector<TargetView> four_hole_views(const core::PinholeCamera& camera, const Eigen::Isometry3d& truth,
                                        const std::vector<testing::Placement>& placements,
                                        const std::vector<std::vector<int>>& ellipse_order) {
  std::vector<TargetView> views;
  for (std::size_t i = 0; i < placements.size(); ++i) {
    const testing::Placement& pl = placements[i];
    const auto [normal, e1, e2] = testing::board_axes(pl);
    TargetView v;
    v.name = "view " + std::to_string(i);
    v.radius_m = 0.12;
    v.image_width = camera.width();
    v.image_height = camera.height();
    std::vector<cv::RotatedRect> ellipses;
    for (const double dy : {0.2, -0.2}) {
      for (const double dx : {-0.25, 0.25}) {
        const Eigen::Vector3d c = pl.center_lidar + dx * e1 - dy * e2;
        std::vector<cv::Point2f> px;
        for (int k = 0; k < 360; ++k) {
          const Eigen::Vector3d p = c + v.radius_m * (std::cos(k * kDeg) * e1 + std::sin(k * kDeg) * e2);
          Eigen::Vector2d uv;
          if (camera.project(truth * p, &uv)) px.emplace_back(static_cast<float>(uv.x()), static_cast<float>(uv.y()));
        }
        v.lidar_centers.push_back(c);
        v.lidar_normals.push_back(normal);
        ellipses.push_back(cv::fitEllipse(px));
      }
    }
    for (const int k : ellipse_order[i]) v.image_ellipses.push_back(ellipses[static_cast<std::size_t>(k)]);
    views.push_back(std::move(v));
  }
  return views;
}

TEST(InitialGuess, AlignRigidRecoversAKnownTransform) {
  const Eigen::Isometry3d T = core::make_transform(core::rotation_from_rpy(0.3, -0.2, 1.1),
                                                   Eigen::Vector3d(0.5, -1.0, 2.0));
  std::vector<Eigen::Vector3d> a = {{1, 0, 0}, {0, 2, 0}, {0, 0, 3}, {1, 1, 1}}, b;
  for (const auto& p : a) b.push_back(T * p);
  const Eigen::Isometry3d est = align_rigid(a, b);
  EXPECT_LT(core::rotation_error_rad(est, T), 1e-9);
  EXPECT_LT(core::translation_error_m(est, T), 1e-9);
}

TEST(InitialGuess, AlignRigidNamesMismatchedLists) {
  const std::vector<Eigen::Vector3d> three = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, two = {{1, 0, 0}, {0, 1, 0}};
  const auto message = [](const auto& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([&] { align_rigid(three, two); }).find("3 and 2 points"), std::string::npos);
  EXPECT_NE(message([&] { align_rigid({}, {}); }).find("0 and 0 points"), std::string::npos);
  EXPECT_NE(message([&] { align_rigid(three, three, three, two); }).find("3 and 2 directions"), std::string::npos);
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

// The image detector lists a view's holes in another order than the LIDAR detector (as for
// a LIDAR mounted rolled against the camera): pairing hole k with ellipse k put the start
// pose tens of degrees off. The pairing is found, and three views leave no doubt.
TEST(InitialGuess, HolesListedInAnotherOrderInTheImageArePairedByTheSearch) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  auto placements = testing::table1_placements();
  placements.resize(3);
  const auto views = four_hole_views(camera, truth, placements, {{3, 2, 1, 0}, {1, 3, 0, 2}, {2, 0, 3, 1}});
  const InitialGuessResult g = closed_form_initial_guess(views, camera);
  ASSERT_TRUE(g.ok) << g.message;
  EXPECT_EQ(g.num_correspondences, 12);
  EXPECT_LT(core::rotation_error_rad(g.T_camera_lidar, truth), 2.0 * kDeg) << g.message;
  EXPECT_LT(core::translation_error_m(g.T_camera_lidar, truth), 0.10) << g.message;
  EXPECT_FALSE(g.ambiguous) << g.ambiguity;
}

// One view of the symmetric four-hole board: the true pose and the one turned 180 degrees
// about the board's normal fit alike, whatever order the image detector lists the holes in.
// The guess says so and takes the pose with the LIDAR the same way up as the camera.
TEST(InitialGuess, OneViewOfASymmetricBoardIsReportedAmbiguous) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  auto placements = testing::table1_placements();
  placements.resize(1);
  for (const std::vector<int>& order : {std::vector<int>{0, 1, 2, 3}, std::vector<int>{3, 2, 1, 0}}) {
    const InitialGuessResult g = closed_form_initial_guess(four_hole_views(camera, truth, placements, {order}), camera);
    ASSERT_TRUE(g.ok) << g.message;
    EXPECT_TRUE(g.ambiguous) << order[0];
    EXPECT_NE(g.ambiguity.find("symmetric"), std::string::npos) << g.ambiguity;
    EXPECT_LT(core::rotation_error_rad(g.T_camera_lidar, truth), 2.0 * kDeg) << g.message;
  }
  // The same rig with the LIDAR mounted upside down (rolled 180 deg about its x axis): the
  // assumption is wrong, the pose is the turned one, and the ambiguity is still reported.
  const Eigen::Isometry3d rolled = truth * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX());
  std::vector<testing::Placement> rolled_placements = placements;
  for (auto& pl : rolled_placements) pl.center_lidar = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()) * pl.center_lidar;
  const InitialGuessResult g = closed_form_initial_guess(four_hole_views(camera, rolled, rolled_placements, {{0, 1, 2, 3}}), camera);
  ASSERT_TRUE(g.ok) << g.message;
  EXPECT_TRUE(g.ambiguous);
  EXPECT_GT(core::rotation_error_rad(g.T_camera_lidar, rolled), 150.0 * kDeg) << g.message;
}

}  // namespace
}  // namespace rgbdt::extrinsics
