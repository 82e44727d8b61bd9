#include "rgbdt/calib_targets/lidar_target.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/log.hpp"
#include "synthetic_scene.hpp"

namespace ct = rgbdt::calib_targets;
namespace fs = std::filesystem;

namespace {

rgbdt::core::TargetSpec paper_target() {
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.3;
  return t;
}

// The requirement: hole centre within 1 cm at 3-5 m with 1 cm range noise.
constexpr double kCenterTolM = 0.01;

}  // namespace

class TiltingRange : public ::testing::TestWithParam<double> {};

TEST_P(TiltingRange, AutomaticCenterWithinOneCentimetre) {
  const double range = GetParam();
  const auto board = rgbdt::test::board_at(range, 0.3, 0.35, -0.2);
  const auto cloud = rgbdt::test::tilting_scan(board, 0.01, 7u);
  const auto det = ct::detect_target_in_cloud(cloud, true, paper_target());
  ASSERT_TRUE(det.ok) << det.reason;
  ASSERT_EQ(det.holes.size(), 1u);
  const auto& h = det.holes[0];
  EXPECT_LT((h.center - board.hole_center(0)).norm(), kCenterTolM) << "method " << det.edge_method;
  EXPECT_GT(h.normal.dot(board.normal()), std::cos(2.0 * M_PI / 180.0));
  EXPECT_EQ(h.circle_points.size(), 360u);
  EXPECT_NEAR(h.radius_m, 0.3, 0.02);  // free fit of noisy edges: 2 cm
  for (const auto& p : h.circle_points) EXPECT_NEAR((p - h.center).norm(), 0.3, 1e-9);
  EXPECT_EQ(det.edge_method, "scan_lines (ring)");
}

INSTANTIATE_TEST_SUITE_P(CalibTargets, TiltingRange, ::testing::Values(3.0, 4.0, 5.0));

TEST(LidarTarget, SeededAlgorithm2MatchesAutomatic) {
  const auto board = rgbdt::test::board_at(4.0, -0.2, -0.3, 0.1);
  const auto cloud = rgbdt::test::tilting_scan(board, 0.01, 11u);
  const Eigen::Vector3d seed = board.T_lidar_board * Eigen::Vector3d(0.45, 0.45, 0.0);
  const auto det = ct::detect_target_in_cloud(cloud, true, paper_target(), {}, seed);
  ASSERT_TRUE(det.ok) << det.reason;
  EXPECT_LT((det.holes[0].center - board.hole_center(0)).norm(), kCenterTolM);
}

TEST(LidarTarget, RecoveredScanLinesWithoutRing) {
  const auto board = rgbdt::test::board_at(4.0, 0.0, 0.2, 0.0);
  const auto cloud = rgbdt::test::spinning_scan(board, 0.01, 3u, 128, 40.0, 0.2);
  const auto det = ct::detect_target_in_cloud(cloud, false, paper_target());
  ASSERT_TRUE(det.ok) << det.reason;
  EXPECT_EQ(det.edge_method, "scan_lines (recovered)");
  EXPECT_LT((det.holes[0].center - board.hole_center(0)).norm(), kCenterTolM);
}

TEST(LidarTarget, OccupancyDetectorForNonRepetitiveLidar) {
  const auto board = rgbdt::test::board_at(4.0, 0.1, -0.25, 0.1);
  const auto cloud = rgbdt::test::random_scan(board, 0.01, 5u);
  ct::LidarDetectionOptions opt;
  opt.edge_method = ct::LidarEdgeMethod::kOccupancy;
  const auto det = ct::detect_target_in_cloud(cloud, false, paper_target(), opt);
  ASSERT_TRUE(det.ok) << det.reason;
  EXPECT_EQ(det.edge_method, "occupancy");
  EXPECT_LT((det.holes[0].center - board.hole_center(0)).norm(), kCenterTolM);
}

// A panel without a hole, 5 m away, behind a round sign at 4 m: the sign's shadow on the
// panel is an empty disc of the target's radius (0.24 m x 5 / 4 = 0.30 m) with panel all
// around it. Only the rays through it tell it from a hole: they end on the sign, in front
// of the panel. The sign itself (0.48 m across) is too small to be the board.
TEST(LidarTarget, AShadowIsNotAHole) {
  auto panel = rgbdt::test::board_at(5.0, 0.0, 0.0, 0.0);
  panel.holes.clear();
  panel.signs.push_back({0.8 * panel.T_lidar_board.translation(), 0.24});
  const auto cloud = rgbdt::test::tilting_scan(panel, 0.005, 3u);
  const auto det = ct::detect_target_in_cloud(cloud, true, paper_target());
  EXPECT_FALSE(det.ok) << "found a hole at " << det.holes.at(0).center.transpose();
  EXPECT_NE(det.reason.find("shadow"), std::string::npos) << det.reason;
}

TEST(LidarTarget, FourHoleBoardInLayoutOrder) {
  auto board = rgbdt::test::board_at(3.5, 0.0, 0.3, 0.0, 0.12);
  board.half_width = 0.6;
  board.half_height = 0.6;
  board.holes = {{-0.3, 0.3}, {0.3, 0.3}, {-0.3, -0.3}, {0.3, -0.3}};  // row-major, top-left first
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.12;
  t.holes_m = board.holes;
  const auto cloud = rgbdt::test::spinning_scan(board, 0.01, 9u, 128, 40.0, 0.15);
  const auto det = ct::detect_target_in_cloud(cloud, true, t);
  ASSERT_TRUE(det.ok) << det.reason;
  ASSERT_EQ(det.holes.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_LT((det.holes[k].center - board.hole_center(k)).norm(), kCenterTolM) << "hole " << k;
  }
}

TEST(LidarTarget, BadInputGivesReasons) {
  const rgbdt::cloud::Cloud empty;
  auto det = ct::detect_target_in_cloud(empty, true, paper_target());
  EXPECT_FALSE(det.ok);
  EXPECT_NE(det.reason.find("empty"), std::string::npos);

  // No board: only the wall and the floor.
  auto board = rgbdt::test::board_at(4.0, 0.0, 0.0, 0.0);
  board.T_lidar_board.translation() = Eigen::Vector3d(-50, 0, 0);  // behind the sensor
  const auto no_board = rgbdt::test::tilting_scan(board, 0.01, 1u);
  det = ct::detect_target_in_cloud(no_board, true, paper_target());
  EXPECT_FALSE(det.ok);
  EXPECT_NE(det.reason.find("no board"), std::string::npos) << det.reason;

  // Seed on the background wall: the wall has no hole.
  const auto good = rgbdt::test::board_at(4.0, 0.0, 0.0, 0.0);
  const auto cloud = rgbdt::test::tilting_scan(good, 0.01, 2u);
  det = ct::detect_target_in_cloud(cloud, true, paper_target(), {}, Eigen::Vector3d(5.5, 2.0, 0.5));
  EXPECT_FALSE(det.ok);
  EXPECT_NE(det.reason.find("seeded board"), std::string::npos) << det.reason;

  rgbdt::core::TargetSpec bad;
  EXPECT_THROW(ct::detect_target_in_cloud(cloud, true, bad), std::invalid_argument);
}

// Real data: PJLab SensorsCalibration LidarCircleDetect (64 rings, 4-hole board at ~3.3 m,
// 2x2 holes 0.6 m apart; the lower holes are crossed by few, poorly ranged rings).
TEST(LidarTargetRealData, PjlabFourHoleBoard) {
  const fs::path dir = fs::path(RGBDT_SHARED_DATA_DIR) /
                       "pjlab-sensorscalibration/lidar2camera/joint_calib/tool/LidarCircleDetect/data";
  ASSERT_TRUE(fs::exists(dir)) << "real data folder missing: " << dir << " (CI keeps ../shared beside the checkout)";
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_EQ(files.size(), 10u);
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.12;
  t.holes_m = {{-0.3, 0.3}, {0.3, 0.3}, {-0.3, -0.3}, {0.3, -0.3}};
  // References of the data README: upper holes near (3.32, 0.97, -0.035) and
  // (3.34, 0.37, -0.035), radius ~0.11-0.12 m. "near": 2 cm (the README's rounding and
  // this LIDAR's per-ring range offsets of a few cm, visible on the board).
  const Eigen::Vector3d upper_left(3.32, 0.97, -0.035), upper_right(3.34, 0.37, -0.035);
  for (std::size_t f = 0; f < files.size(); f += 3) {
    const auto loaded = rgbdt::cloud::load_pcd(files[f].string());
    const auto det = ct::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, t);
    ASSERT_TRUE(det.ok) << files[f] << ": " << det.reason;
    ASSERT_EQ(det.holes.size(), 4u);
    for (const auto& h : det.holes) {
      std::cout << files[f].filename().string() << " hole " << h.center.transpose() << " r "
                << h.radius_m << (h.radius_measured ? "" : " (not measured)") << " rms " << h.rms_m
                << " edges " << h.edge_points.size() << "\n";
    }
    EXPECT_LT((det.holes[0].center - upper_left).norm(), 0.02);
    EXPECT_LT((det.holes[1].center - upper_right).norm(), 0.02);
    for (int k : {0, 1}) {
      EXPECT_TRUE(det.holes[k].radius_measured);
      EXPECT_NEAR(det.holes[k].radius_m, 0.115, 0.01);
    }
    // Lower holes: 0.6 m below the upper ones on the board (layout), 3 cm tolerance for
    // the few rings that cross them.
    for (int k : {2, 3}) {
      EXPECT_NEAR((det.holes[k].center - det.holes[k - 2].center).norm(), 0.6, 0.03) << "hole " << k;
    }
  }
}

// Real data: discocal LIDAR sample (no ring field): 4 holes of radius 0.075 m, 0.24 m apart,
// at ~1.8 m. No reference positions: the layout must be recovered (spacing, radius).
TEST(LidarTargetRealData, DiscocalFourHoleBoardWithoutRing) {
  const fs::path dir = fs::path(RGBDT_SHARED_DATA_DIR) / "discocal/lidar_commit_c1fe5ab/sample_data/lidars";
  ASSERT_TRUE(fs::exists(dir)) << "real data folder missing: " << dir << " (CI keeps ../shared beside the checkout)";
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.075;
  t.holes_m = {{-0.12, 0.12}, {0.12, 0.12}, {-0.12, -0.12}, {0.12, -0.12}};
  for (int f = 0; f < 4; ++f) {
    const fs::path file = dir / ("point_cloud_00" + std::to_string(f) + ".pcd");
    const auto loaded = rgbdt::cloud::load_pcd(file.string());
    EXPECT_FALSE(loaded.has_ring);
    const auto det = ct::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, t);
    ASSERT_TRUE(det.ok) << file << ": " << det.reason;
    ASSERT_EQ(det.holes.size(), 4u);
    std::cout << file.filename().string() << " method " << det.edge_method << "\n";
    for (const auto& h : det.holes) {
      std::cout << "  hole " << h.center.transpose() << " r " << h.radius_m << " rms " << h.rms_m
                << " edges " << h.edge_points.size() << "\n";
      EXPECT_NEAR(h.center.norm(), 1.8, 0.4);
      if (h.radius_measured) {
        EXPECT_NEAR(h.radius_m, 0.075, 0.01);
      }
    }
    // Layout: neighbours 0.24 m apart (1 cm), diagonals 0.34 m.
    EXPECT_NEAR((det.holes[0].center - det.holes[1].center).norm(), 0.24, 0.01);
    EXPECT_NEAR((det.holes[0].center - det.holes[2].center).norm(), 0.24, 0.01);
    EXPECT_NEAR((det.holes[3].center - det.holes[1].center).norm(), 0.24, 0.01);
    EXPECT_NEAR((det.holes[3].center - det.holes[2].center).norm(), 0.24, 0.01);
  }
}
