// A written calibration session is complete, readable through core, consistent with its
// ground truth, and the same for the same seed.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/calibration_session.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::sim {
namespace {

namespace fs = std::filesystem;


std::string read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

Eigen::Isometry3d pose_from_yaml(const YAML::Node& n) {
  const auto t = n["translation"].as<std::vector<double>>();
  const auto q = n["rotation_quaternion"].as<std::vector<double>>();
  return core::make_transform(core::quaternion_from_xyzw(Eigen::Vector4d(q[0], q[1], q[2], q[3])).toRotationMatrix(),
                              Eigen::Vector3d(t[0], t[1], t[2]));
}

CalibrationSessionOptions small_options() {
  CalibrationSessionOptions o;
  o.views = 2;
  o.supersampling = 2;  // this test does not measure edges (camera_sim_test does)
  o.seed = 5;
  return o;
}

TEST(CalibrationSession, WritesEveryFileOfTheContractReadableByCore) {
  const fs::path dir = test::temp_path("session");
  const CalibrationSessionOptions options = small_options();
  const CalibrationSessionResult result = write_calibration_session(dir.string(), options);
  ASSERT_EQ(result.views.size(), 2u);

  const core::CalibrationSession session = core::read_calibration_session(dir.string());
  EXPECT_EQ(session.target.type, "circle_hole");
  EXPECT_DOUBLE_EQ(session.target.radius_m, 0.30);
  ASSERT_EQ(session.views.size(), 2u);
  EXPECT_EQ(core::read_camera_info(session.cameras.at("rgb").intrinsics).width, 1288);
  EXPECT_EQ(core::read_camera_info(session.cameras.at("thermal").intrinsics).width, 640);
  for (const auto& v : session.views) {
    const cv::Mat rgb = cv::imread(v.images.at("rgb"), cv::IMREAD_UNCHANGED);
    const cv::Mat th = cv::imread(v.images.at("thermal"), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(rgb.cols, 1288);
    EXPECT_EQ(rgb.rows, 964);
    EXPECT_EQ(th.type(), CV_16UC1);
    EXPECT_EQ(th.cols, 640);
    EXPECT_EQ(th.rows, 512);
    const cloud::LoadedCloud c = cloud::load_pcd(v.cloud);
    EXPECT_TRUE(c.has_intensity && c.has_ring && c.has_t);
    EXPECT_GT(c.cloud->size(), 10000u);
    ASSERT_TRUE(v.lidar_seed.has_value());
    EXPECT_EQ(v.image_seeds.count("rgb"), 1u);
  }
  for (const char* f : {"true_calib/extrinsics_rgb.yaml", "true_calib/extrinsics_thermal.yaml", "true_calib/rgb.yaml",
                        "true_calib/thermal.yaml", "true_calib/report.md", "ground_truth.yaml"}) {
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  }
  const core::Extrinsics e = core::read_extrinsics((dir / "true_calib/extrinsics_rgb.yaml").string());
  EXPECT_EQ(e.parent_frame, "rgb");
  EXPECT_EQ(e.child_frame, "lidar");
  EXPECT_LT(core::rotation_error_rad(e.T_parent_child, options.rig.T_rgb_lidar), 1e-9);
  EXPECT_LT(core::translation_error_m(e.T_parent_child, options.rig.T_rgb_lidar), 1e-9);
}

TEST(CalibrationSession, GroundTruthAgreesWithTheCloudsAndTheContract) {
  const fs::path dir = test::temp_path("session");
  CalibrationSessionOptions options = small_options();
  options.rig.lidar.mixed_pixels = false;
  write_calibration_session(dir.string(), options);
  const YAML::Node gt = YAML::LoadFile((dir / "ground_truth.yaml").string());
  // The extrinsics entry parses as an extrinsics YAML and equals the rig.
  const core::Extrinsics thermal = core::parse_extrinsics(YAML::Dump(gt["extrinsics"]["thermal"]), "gt");
  EXPECT_LT(core::rotation_error_rad(thermal.T_parent_child, options.rig.T_thermal_lidar), 1e-9);
  EXPECT_EQ(gt["intrinsics"]["rgb"].as<std::string>(), "true_calib/rgb.yaml");
  EXPECT_DOUBLE_EQ(gt["lidar"]["range_noise_sigma_m"].as<double>(), 0.01);
  const double radius = gt["target"]["radius"].as<double>();
  const core::CalibrationSession session = core::read_calibration_session(dir.string());
  ASSERT_EQ(gt["target"]["views"].size(), session.views.size());
  for (size_t i = 0; i < session.views.size(); ++i) {
    const YAML::Node v = gt["target"]["views"][i];
    const Eigen::Isometry3d T_lidar_board = pose_from_yaml(v["T_lidar_board"]);
    const auto c = v["hole_centers_lidar"][0].as<std::vector<double>>();
    const auto n = v["normal_lidar"].as<std::vector<double>>();
    const Eigen::Vector3d centre(c[0], c[1], c[2]), normal(n[0], n[1], n[2]);
    EXPECT_LT((centre - T_lidar_board.translation()).norm(), 1e-9);
    EXPECT_NEAR(normal.norm(), 1.0, 1e-9);
    EXPECT_GT(normal.dot(-centre), 0.0);  // towards the LIDAR
    // Board points: on the board plane within the noise and outside the hole; none inside it.
    const cloud::LoadedCloud cloud = cloud::load_pcd(session.views[i].cloud);
    int on_board = 0, in_hole = 0;
    for (const auto& p : *cloud.cloud) {
      const Eigen::Vector3d q = T_lidar_board.inverse() * Eigen::Vector3d(p.x, p.y, p.z);
      if (std::abs(q.x()) > 0.6 || std::abs(q.y()) > 0.6) continue;
      const double rho = std::hypot(q.x(), q.y());
      if (std::abs(q.z()) < 0.05) {
        ++on_board;
        // 5 sigma of the range noise (along beams within 65 deg of the normal: / cos).
        EXPECT_LT(std::abs(q.z()), 5 * 0.01 / std::cos(65.0 * M_PI / 180.0));
        if (rho < radius - 0.02) ++in_hole;
      }
    }
    EXPECT_GT(on_board, 100);
    EXPECT_EQ(in_hole, 0);
  }
}

TEST(CalibrationSession, SameSeedGivesIdenticalFiles) {
  CalibrationSessionOptions options = small_options();
  options.views = 1;
  options.supersampling = 1;
  const fs::path a = test::temp_path("a"), b = test::temp_path("b"), c = test::temp_path("c");
  write_calibration_session(a.string(), options);
  write_calibration_session(b.string(), options);
  options.seed = 6;
  write_calibration_session(c.string(), options);
  for (const char* f : {"clouds/000.pcd", "rgb/000.png", "thermal/000.png", "ground_truth.yaml", "session.yaml"}) {
    EXPECT_EQ(read_bytes(a / f), read_bytes(b / f)) << f;
    EXPECT_NE(read_bytes(a / f), read_bytes(c / f)) << f;
  }
}

TEST(CalibrationSession, FourHoleBoardListsHolesRowMajorFromTheTopLeft) {
  const fs::path dir = test::temp_path("four");
  CalibrationSessionOptions options = small_options();
  options.views = 1;
  options.holes = 4;
  options.min_distance_m = 3.0;
  options.max_distance_m = 5.0;
  const CalibrationSessionResult r = write_calibration_session(dir.string(), options);
  ASSERT_EQ(r.target.holes_m.size(), 4u);
  EXPECT_LT(r.target.holes_m[0].x(), r.target.holes_m[1].x());  // left before right
  EXPECT_GT(r.target.holes_m[0].y(), r.target.holes_m[2].y());  // top row first
  ASSERT_EQ(r.views[0].hole_centers_lidar.size(), 4u);
  const core::CalibrationSession s = core::read_calibration_session(dir.string());
  EXPECT_EQ(s.target.holes_m.size(), 4u);
}

TEST(CalibrationSession, RejectsBadOptionsNamingTheValue) {
  CalibrationSessionOptions options;
  options.holes = 3;
  try {
    write_calibration_session(test::temp_path("bad").string(), options);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("holes 3"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rgbdt::sim
