// The spinning and dense LIDAR models: geometry of the beams, range noise, the beam
// footprint's widening of holes, and the PCD without a ring field.
#include "rgbdt/sim/multibeam_sim.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/calibration_session.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A one-hole board (r 0.3 m) facing the sensor at 5 m along +x, a cloth 1.2 m behind.
Scene board_scene(const core::TargetSpec& target, double distance) {
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();  // board x right as seen from the sensor
  R.col(1) = Eigen::Vector3d::UnitZ();
  R.col(2) = -Eigen::Vector3d::UnitX();
  return make_calibration_scene(target, core::make_transform(R, Eigen::Vector3d(distance, 0, 0)), 1.2, TimeOfDay::kDay);
}

struct BoardStats {
  int points = 0;
  double nearest_to_hole_axis = 1e9;  ///< smallest distance of a board point from the hole's axis [m]
  double range_rms = 0.0;             ///< RMS of x - distance over the board points [m]
};

BoardStats board_stats(const cloud::Cloud& cloud, double distance, double half, double band = 0.1) {
  BoardStats s;
  double ss = 0.0;
  for (const auto& p : cloud.points) {
    if (std::abs(p.x - distance) > band || std::abs(p.y) > half || std::abs(p.z) > half) continue;
    ++s.points;
    ss += (p.x - distance) * (p.x - distance);
    s.nearest_to_hole_axis = std::min(s.nearest_to_hole_axis, std::hypot(double(p.y), double(p.z)));
  }
  s.range_rms = s.points ? std::sqrt(ss / s.points) : 0.0;
  return s;
}

TEST(SpinningLidar, RingsAtTheirElevationsWithRangeNoise) {
  const core::TargetSpec target = calibration_target(1, 0.3);
  const Scene scene = board_scene(target, 5.0);
  SpinningLidarOptions o = SpinningLidarOptions::preset(16);
  o.beam.range_sigma_m = 0.01;
  const cloud::Cloud cloud = simulate_spinning(scene, o, 30.0 * kDeg, 4u);
  std::set<int> rings;
  for (const auto& p : cloud.points) {
    const double el = std::atan2(p.z, std::hypot(p.x, p.y)) / kDeg;
    // Each beam keeps its elevation: -15 + 2 ring [deg] (float storage: 1e-4 deg).
    EXPECT_NEAR(el, -15.0 + 2.0 * p.ring, 1e-3);
    rings.insert(p.ring);
  }
  EXPECT_GE(rings.size(), 8u);  // downward beams hit the ground, upward the board and cloth
  const BoardStats s = board_stats(cloud, 5.0, 0.55);
  // The 1.1 m window at 5 m: rings at -5, -3, ..., 5 deg (6 rings), 12.6 deg / 0.2 deg = 63
  // points each, minus the hole's chords at z = 5 tan(1 deg) (0.574 m) and 5 tan(3 deg)
  // (0.29 m), 2 (0.574 + 0.29) / (5 * 0.2 deg) = 99 points: ~279.
  EXPECT_NEAR(s.points, 279, 10);
  // Range noise 1 cm; a 5% band for the sample size (several hundred points).
  EXPECT_NEAR(s.range_rms, 0.01, 0.0015);
}

TEST(DenseLidar, RosetteCoversTheBoardDenselyWithoutRing) {
  const core::TargetSpec target = calibration_target(1, 0.3);
  const Scene scene = board_scene(target, 5.0);
  DenseLidarOptions o;
  o.duration_s = 2.0;
  const cloud::Cloud cloud = simulate_dense(scene, o, 9u);
  const BoardStats s = board_stats(cloud, 5.0, 0.55);
  // The board covers ~(1.2 / 5)^2 / (pi (0.335)^2) of the 38.4 deg cone: ~16% of 200k points
  // minus the hole; the rosette is denser at the rim than at the centre, so a wide band.
  EXPECT_GT(s.points, 15000);
  EXPECT_NEAR(s.range_rms, 0.02, 0.002);
}

TEST(BeamFootprint, WidensHolesByPartOfTheFootprint) {
  const core::TargetSpec target = calibration_target(1, 0.3);
  const Scene scene = board_scene(target, 5.0);
  DenseLidarOptions o;
  o.duration_s = 2.0;
  o.beam.range_sigma_m = 0.0;
  o.beam.divergence_rad = 0.01;  // 5 cm footprint at 5 m
  // Points within 1 cm of the board plane (no range noise here).
  const BoardStats wide = board_stats(simulate_dense(scene, o, 3u), 5.0, 0.55, 0.01);
  o.beam.divergence_rad = 0.0;
  const BoardStats sharp = board_stats(simulate_dense(scene, o, 3u), 5.0, 0.55, 0.01);
  // Without footprint the board's points reach the rim (within the point spacing, ~5 mm).
  // With it, a beam whose footprint (rim rays 2.5 cm from the centre ray, along two axes)
  // reaches into the hole mixes in the cloth 1.2 m behind: even one rim ray of five on the
  // black cloth (NIR reflectivity 0.06 against the board's 0.80) moves the range ~2 cm back, off
  // the board. The hole looks wider by 2.5 cm along the rays' axes, 1.8 cm between them.
  EXPECT_LT(sharp.nearest_to_hole_axis, 0.3 + 0.006);
  EXPECT_GT(wide.nearest_to_hole_axis, 0.3 + 0.015);
  EXPECT_LT(wide.nearest_to_hole_axis, 0.3 + 0.026);
}

TEST(DenseLidar, PcdWithoutRingFieldLoads) {
  const core::TargetSpec target = calibration_target(1, 0.3);
  const Scene scene = board_scene(target, 5.0);
  DenseLidarOptions o;
  o.duration_s = 0.05;
  const cloud::Cloud cloud = simulate_dense(scene, o, 1u);
  const std::string path = (test::temp_path("dense_pcd") / "cloud.pcd").string();
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  save_pcd_without_ring(path, cloud);
  const cloud::LoadedCloud loaded = cloud::load_pcd(path);
  EXPECT_FALSE(loaded.has_ring);
  EXPECT_TRUE(loaded.has_t);
  ASSERT_EQ(loaded.cloud->size(), cloud.size());
  EXPECT_FLOAT_EQ(loaded.cloud->points[10].x, cloud.points[10].x);
  EXPECT_FLOAT_EQ(loaded.cloud->points[10].t, cloud.points[10].t);
}

TEST(LidarKinds, NamesRoundTripAndBadNamesAreRejected) {
  for (const LidarKind k : {LidarKind::kTilt, LidarKind::kSpinning16, LidarKind::kSpinning32, LidarKind::kSpinning64,
                            LidarKind::kDense}) {
    EXPECT_EQ(lidar_kind_from_string(to_string(k)), k);
  }
  try {
    lidar_kind_from_string("velodyne");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("velodyne"), std::string::npos);
  }
  EXPECT_THROW(SpinningLidarOptions::preset(20), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::sim
