// Mapping and coloring-setup sessions: the raw stream reads back (also through MRPT's own
// rawlog-edit), its timestamps follow the motion profile, and every index and truth file
// agrees with the data.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/mapping_session.hpp"
#include "rgbdt/sim/rawlog.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::sim {
namespace {

namespace fs = std::filesystem;


MappingSessionOptions small_mapping() {
  MappingSessionOptions o;
  o.duration_s = 1.3;  // two complete tilts of 0.6 s
  o.rig.rgb_fps = 1.0;
  o.rig.thermal_fps = 2.0;
  o.supersampling = 1;
  o.seed = 3;
  return o;
}

// The checks below share one session (writing it is the slow part; ctest runs every
// TEST in its own process), so one TEST calls them in turn.
fs::path mapping_dir_;
const fs::path& mapping_dir() { return mapping_dir_; }
void cloud_points_match_the_raw_scans_and_the_trajectory_is_smooth();

void session_yaml_names_every_stream_and_core_reads_it() {
  const core::MappingSession s = core::read_mapping_session(mapping_dir().string());
  EXPECT_TRUE(fs::exists(s.lidar.rawlog));
  EXPECT_TRUE(fs::exists(s.lidar.rig));
  const auto clouds = core::read_time_index(s.lidar.clouds);
  EXPECT_EQ(clouds.size(), 2u);
  for (const auto& c : clouds) EXPECT_GT(cloud::load_pcd(c.file).cloud->size(), 5000u);
  const auto rgb = core::read_time_index(s.cameras.at("rgb").frames);
  const auto thermal = core::read_time_index(s.cameras.at("thermal").frames);
  EXPECT_EQ(rgb.size(), 2u);      // 1.3 s at 1 fps
  EXPECT_EQ(thermal.size(), 3u);  // 1.3 s at 2 fps
  EXPECT_EQ(cv::imread(rgb[0].file, cv::IMREAD_UNCHANGED).type(), CV_8UC3);
  EXPECT_EQ(cv::imread(thermal[0].file, cv::IMREAD_UNCHANGED).type(), CV_16UC1);
  ASSERT_TRUE(s.cameras.at("thermal").radiometry.has_value());
  EXPECT_EQ(s.cameras.at("thermal").radiometry->type, "linear");
  EXPECT_DOUBLE_EQ(s.cameras.at("thermal").radiometry->parameters.at("kelvin_per_count"), 0.04);
  const YAML::Node gt = YAML::LoadFile((mapping_dir() / "ground_truth.yaml").string());
  EXPECT_EQ(gt["lidar"]["rig"].as<std::string>(), "tilt_rig.yaml");
  EXPECT_EQ(gt["trajectory"].as<std::string>(), "ground_truth/trajectory.csv");
  EXPECT_TRUE(fs::exists(mapping_dir() / "true_calib" / "extrinsics_thermal.yaml"));

  // Per-beam true temperatures: one row per raw scan, one column per beam; almost every
  // valid beam has one (only mixed pixels at depth edges do not), and all are apparent
  // temperatures of the day's materials (emissivity-weighted with a 250 K sky: 293-315 K).
  const YAML::Node beams = gt["beam_temperature"];
  ASSERT_TRUE(beams) << "ground_truth.yaml lacks beam_temperature";
  const cv::Mat truth = cv::imread((mapping_dir() / beams["image"].as<std::string>()).string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(truth.type(), CV_16UC1);
  EXPECT_EQ(truth.rows, 52);  // 1.3 s / 25 ms
  EXPECT_EQ(truth.cols, 1081);
  EXPECT_DOUBLE_EQ(beams["first_scan_time_s"].as<double>(), small_mapping().trajectory.start_time_s);
  const RawlogContents raw = read_rawlog((mapping_dir() / "lidar.rawlog").string());
  const double kelvin_per_unit = beams["kelvin_per_unit"].as<double>();
  int valid = 0, with_truth = 0, in_range = 0;
  for (int k = 0; k < truth.rows; ++k) {
    for (int i = 0; i < truth.cols; ++i) {
      const std::uint16_t v = truth.at<std::uint16_t>(k, i);
      if (!raw.scans[static_cast<size_t>(k)].valid[static_cast<size_t>(i)]) {
        EXPECT_EQ(v, 0) << "scan " << k << " beam " << i;
        continue;
      }
      ++valid;
      if (v == 0) continue;
      ++with_truth;
      in_range += v * kelvin_per_unit > 250.0 && v * kelvin_per_unit < 330.0;
    }
  }
  EXPECT_GT(with_truth, 0.95 * valid) << with_truth << " of " << valid;
  EXPECT_EQ(in_range, with_truth);
}

void rawlog_timestamps_follow_the_scan_and_encoder_rates() {
  const RawlogContents raw = read_rawlog((mapping_dir() / "lidar.rawlog").string());
  const MappingSessionOptions o = small_mapping();
  const core::TiltRig rig = core::read_tilt_rig((mapping_dir() / "tilt_rig.yaml").string());
  EXPECT_EQ(raw.other_objects, 0);
  ASSERT_EQ(raw.scans.size(), 52u);  // 1.3 s / 25 ms
  ASSERT_EQ(raw.encoder.size(), 130u);  // 1.3 s at 100 Hz
  for (size_t i = 0; i < raw.scans.size(); ++i) {
    // MRPT stores time in 100 ns ticks.
    EXPECT_NEAR(raw.scans[i].time_s, o.trajectory.start_time_s + 0.025 * i, 2e-7);
    EXPECT_EQ(raw.scans[i].range_m.size(), static_cast<size_t>(rig.scanner.beams));
  }
  // Encoder angles are the motion profile (triangle, -30..30 deg in 0.6 s) quantised to
  // the counts of tilt_rig.yaml.
  TiltProfile profile = o.rig.lidar.profile;
  profile.start_time_s = o.trajectory.start_time_s;
  for (const EncoderSample& e : raw.encoder) {
    EXPECT_NEAR(e.angle_rad, rig.motor.angle_from_count(e.count), 1e-12);
    EXPECT_LE(std::abs(e.angle_rad - profile.angle_rad(e.time_s)), M_PI / rig.motor.counts_per_revolution + 1e-6);
  }
}

void rawlog_is_readable_by_mrpt_rawlog_edit() {
  // rawlog-edit comes with mrpt-apps (scripts/install-deps).
  const std::string log = (mapping_dir() / "rawlog_edit_info.txt").string();
  const std::string cmd = "rawlog-edit --info -i '" + (mapping_dir() / "lidar.rawlog").string() + "' > '" + log + "' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "rawlog-edit failed, see " << log;
  std::ifstream f(log);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Observations format               : Yes"), std::string::npos) << text;
  EXPECT_NE(text.find("HOKUYO /     52 /40.000"), std::string::npos) << text;         // 40 scans/s
  EXPECT_NE(text.find("TILT_ENCODER /    130 /100.000"), std::string::npos) << text;  // 100 Hz
}

TEST(MappingSession, ShortSessionIsCompleteConsistentAndReadableByMrpt) {
  mapping_dir_ = test::temp_path("session");
  const MappingSessionResult r = write_mapping_session(mapping_dir_.string(), small_mapping());
  EXPECT_EQ(r.clouds, 2);
  {
    SCOPED_TRACE("session.yaml");
    session_yaml_names_every_stream_and_core_reads_it();
  }
  {
    SCOPED_TRACE("rawlog timestamps");
    rawlog_timestamps_follow_the_scan_and_encoder_rates();
  }
  {
    SCOPED_TRACE("rawlog-edit");
    rawlog_is_readable_by_mrpt_rawlog_edit();
  }
  {
    SCOPED_TRACE("clouds and trajectory");
    cloud_points_match_the_raw_scans_and_the_trajectory_is_smooth();
  }
}

TEST(MappingSession, SameSeedSameRawStream) {
  MappingSessionOptions o = small_mapping();
  o.duration_s = 0.3;
  o.write_images = false;
  const fs::path a = test::temp_path("a"), b = test::temp_path("b");
  write_mapping_session(a.string(), o);
  write_mapping_session(b.string(), o);
  const RawlogContents ra = read_rawlog((a / "lidar.rawlog").string()), rb = read_rawlog((b / "lidar.rawlog").string());
  ASSERT_EQ(ra.scans.size(), rb.scans.size());
  for (size_t i = 0; i < ra.scans.size(); ++i) EXPECT_EQ(ra.scans[i].range_m, rb.scans[i].range_m);
}

void cloud_points_match_the_raw_scans_and_the_trajectory_is_smooth() {
  const core::MappingSession s = core::read_mapping_session(mapping_dir().string());
  const RawlogContents raw = read_rawlog(s.lidar.rawlog);
  const auto clouds = core::read_time_index(s.lidar.clouds);
  // Valid returns of tilt 0 (24 scans) equal the points of the first cloud.
  size_t valid = 0;
  for (size_t i = 0; i < 24; ++i) {
    for (char v : raw.scans[i].valid) valid += v != 0;
  }
  EXPECT_EQ(cloud::load_pcd(clouds[0].file).cloud->size(), valid);
  EXPECT_NEAR(clouds[1].time_s - clouds[0].time_s, 0.6, 0.02);
  // Trajectory: ~1 m/s, 100 Hz rows.
  std::ifstream f(s.trajectory);
  std::string line;
  std::getline(f, line);
  EXPECT_EQ(line, "time_s,x,y,z,qx,qy,qz,qw");
  std::vector<Eigen::Vector4d> rows;
  while (std::getline(f, line)) {
    double v[8];
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
                          &v[6], &v[7]),
              8);
    rows.emplace_back(v[0], v[1], v[2], v[3]);
  }
  ASSERT_GT(rows.size(), 100u);
  for (size_t i = 1; i < rows.size(); ++i) {
    const double speed = (rows[i].tail<3>() - rows[i - 1].tail<3>()).norm() / (rows[i][0] - rows[i - 1][0]);
    EXPECT_NEAR(speed, 1.0, 0.15);
  }
}

TEST(ColoringSetup, CardPointsLieAtEachDepthAndFramesShareTheCloudTimes) {
  const fs::path dir = test::temp_path("setup");
  ColoringSetupOptions o;
  o.depths_m = {5.0, 12.0};
  o.supersampling = 1;
  o.rig.lidar.mixed_pixels = false;
  write_coloring_setup(dir.string(), o);
  const core::MappingSession s = core::read_mapping_session(dir.string());
  const auto clouds = core::read_time_index(s.lidar.clouds);
  const auto rgb = core::read_time_index(s.cameras.at("rgb").frames);
  ASSERT_EQ(clouds.size(), 2u);
  ASSERT_EQ(rgb.size(), 2u);
  const YAML::Node gt = YAML::LoadFile((dir / "ground_truth.yaml").string());
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_DOUBLE_EQ(clouds[i].time_s, rgb[i].time_s);
    EXPECT_DOUBLE_EQ(gt["coloring_setup"]["views"][i]["depth_m"].as<double>(), o.depths_m[i]);
    // Points in front of the card's footprint lie on the card plane x = depth (within 5 sigma).
    int on_card = 0;
    const cloud::LoadedCloud loaded = cloud::load_pcd(clouds[i].file);  // owns the points while we loop
    for (const auto& p : *loaded.cloud) {
      if (std::abs(p.y) < 0.4 && std::abs(p.z) < 0.25 && p.x < o.depths_m[i] + 0.5) {
        EXPECT_NEAR(p.x, o.depths_m[i], 0.05);
        ++on_card;
      }
    }
    EXPECT_GT(on_card, 20);
  }
}

}  // namespace
}  // namespace rgbdt::sim
