// Ray casting against primitives with known analytic answers.
#include <gtest/gtest.h>

#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {
namespace {

Scene scene_with_materials(int* grey, int* dark) {
  Scene scene;
  Material m;
  *grey = scene.add_material(m);
  m.name = "dark";
  m.albedo_rgb = {0.05, 0.05, 0.05};
  *dark = scene.add_material(m);
  return scene;
}

// A board 4 m ahead of the origin, facing it (board z towards -x of the world).
Eigen::Isometry3d board_ahead(double x) {
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();  // right as seen from the origin
  R.col(1) = Eigen::Vector3d::UnitZ();   // up
  R.col(2) = -Eigen::Vector3d::UnitX();  // towards the origin
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = Eigen::Vector3d(x, 0, 0);
  return T;
}

TEST(Scene, PlaneHitDistanceAndNormalFaceTheRay) {
  int grey = 0, dark = 0;
  Scene scene = scene_with_materials(&grey, &dark);
  scene.add_plane({0, 0, -1.5}, Eigen::Vector3d::UnitZ(), grey);
  const auto hit = scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, -1));
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance, 1.5 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(hit->point.z(), -1.5, 1e-12);
  EXPECT_NEAR(hit->normal.z(), 1.0, 1e-12);
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 0.1)));
}

TEST(Scene, RayThroughBoardHoleHitsWhatIsBehind) {
  int grey = 0, dark = 0;
  Scene scene = scene_with_materials(&grey, &dark);
  BoardSpec board;
  board.T_world_board = board_ahead(4.0);
  board.size_m = {1.2, 1.2};
  board.holes_m = {{0.0, 0.0}};
  board.hole_radius_m = 0.3;
  board.material = grey;
  const int b = scene.add_board(board);
  const int wall = scene.add_plane({6, 0, 0}, Eigen::Vector3d::UnitX(), dark);
  // Just inside the hole edge: the wall; just outside: the board.
  const double a = 0.29 / 4.0, c = 0.31 / 4.0;
  auto in = scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, a, 0));
  auto out = scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, c));
  ASSERT_TRUE(in && out);
  EXPECT_EQ(in->primitive, wall);
  EXPECT_EQ(out->primitive, b);
  EXPECT_NEAR(out->point.x(), 4.0, 1e-12);
  // Beyond the board's edge (0.6 m) the wall again.
  auto beyond = scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(4, 0.61, 0));
  ASSERT_TRUE(beyond);
  EXPECT_EQ(beyond->primitive, wall);
}

TEST(Scene, CheckerboardSquaresAlternateFromADarkTopLeft) {
  int grey = 0, dark = 0;
  Scene scene = scene_with_materials(&grey, &dark);
  BoardSpec board;
  board.T_world_board = board_ahead(2.0);
  board.size_m = {0.6, 0.5};
  board.material = grey;
  board.dark_material = dark;
  board.squares_x = 5;
  board.squares_y = 4;
  board.square_m = 0.1;
  board.pattern_top_left_m = {-0.25, 0.2};
  scene.add_board(board);
  // Board point (x, y) is seen along world direction (2, -x, y).
  auto at = [&](double x, double y) { return scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d(2, -x, y)); };
  EXPECT_EQ(at(-0.2, 0.15)->material, dark);   // square (0, 0)
  EXPECT_EQ(at(-0.1, 0.15)->material, grey);   // square (1, 0)
  EXPECT_EQ(at(-0.1, 0.05)->material, dark);   // square (1, 1)
  EXPECT_EQ(at(0.28, 0.0)->material, grey);    // border outside the pattern
  EXPECT_EQ(at(0.28, 0.0)->region, 0);
}

TEST(Scene, BoxCylinderAndSphereDistances) {
  int grey = 0, dark = 0;
  Scene scene = scene_with_materials(&grey, &dark);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(5, 0, 0);
  scene.add_box(T, {0.5, 1.0, 1.0}, grey);
  scene.add_cylinder({0, 5, -1}, 0.25, 3.0, grey);
  scene.add_sphere({0, 0, 7}, 1.0, grey);
  EXPECT_NEAR(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX())->distance, 4.5, 1e-12);
  EXPECT_NEAR(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY())->distance, 4.75, 1e-12);
  EXPECT_NEAR(scene.intersect(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ())->distance, 6.0, 1e-12);
  // Above the cylinder's top (z = 2): nothing.
  EXPECT_FALSE(scene.intersect(Eigen::Vector3d(0, 0, 2.5), Eigen::Vector3d::UnitY()));
}

TEST(Scene, RejectsInvalidMaterialsAndIndices) {
  Scene scene;
  Material m;
  m.emissivity = 1.5;
  EXPECT_THROW(scene.add_material(m), std::invalid_argument);
  EXPECT_THROW(scene.add_plane({0, 0, 0}, Eigen::Vector3d::UnitZ(), 0), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::sim
