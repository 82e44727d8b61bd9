// rgbdt_import as a user runs it: the real ROS 1 board bags (../shared/data/art-bp-calib)
// imported and checked against what the bag holds, still intervals of a ROS 1 bag written with
// rosbag::Bag, bad input, and the stillness and conversion parts on their own.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "convert.hpp"
#include "import_test_util.hpp"
#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"
#include "still.hpp"

namespace rgbdt::import {
namespace {

namespace fs = std::filesystem;

struct AppRun {
  int exit_code;
  std::string output;
};

AppRun run_import(const std::string& args, const fs::path& log) {
  fs::create_directories(log.parent_path());
  const int status = std::system(
      (test::built_program("rgbdt_import") + " " + args + " > " + log.string() + " 2>&1").c_str());
  std::ifstream f(log);
  std::stringstream ss;
  ss << f.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

fs::path board_bag(const std::string& pose) {
  const fs::path path = fs::path(RGBDT_SHARED_DATA_DIR) / "art-bp-calib" / "calib_data" / "scene" /
                        (pose + "_short.bag");
  if (!fs::is_regular_file(path)) ADD_FAILURE() << "missing real-data file " << path;
  return path;
}

// What the bag holds on one PointCloud2 topic: per message, the returns (finite, not at the
// origin) and the time of the earliest one.
struct BagCloud {
  std::size_t finite = 0;
  std::int64_t first_time_ns = 0;
};
std::vector<BagCloud> bag_clouds(const fs::path& path, const std::string& topic) {
  bag::ReadOptions options;
  options.topics = {topic};
  const auto reader = bag::open_bag(path, options);
  std::vector<BagCloud> out;
  while (const auto m = reader->next()) {
    const auto context = bag::context_of(*m);
    const auto points =
        bag::extract_points(bag::decode_point_cloud2(m->data, m->size, context), context);
    BagCloud c;
    c.first_time_ns = std::numeric_limits<std::int64_t>::max();
    for (std::size_t i = 0; i < points.xyz.size(); ++i) {
      const auto& p = points.xyz[i];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
      if (p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0) continue;  // the driver's "no return"
      ++c.finite;
      c.first_time_ns = std::min(c.first_time_ns, points.time_ns[i]);
    }
    out.push_back(c);
  }
  return out;
}

// The board of the art-bp-calib data (PROVENANCE.md: 4 holes r 0.12 m, 0.5 x 0.4 m apart).
const char* kBoardTarget =
    "'{type: circle_hole, radius: 0.12, holes: [[-0.25, 0.2], [0.25, 0.2], [-0.25, -0.2], [0.25, "
    "-0.2]]}'";

TEST(ImportRealBag, CalibrationKindAccumulatesTheBagsCloudsIntoOneView) {
  const fs::path bag = board_bag("left");
  const fs::path out = test::temp_path("session");
  const AppRun run =
      run_import(bag.string() + " --out " + out.string() +
                     " --kind calibration --lidar /lidar_points --target " + kBoardTarget,
                 out.string() + ".log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("kept as view 000"), std::string::npos) << run.output;

  const core::CalibrationSession session = core::read_calibration_session(out.string());
  EXPECT_EQ(session.target.radius_m, 0.12);
  EXPECT_EQ(session.target.holes_m.size(), 4u);
  EXPECT_TRUE(session.cameras.empty());
  ASSERT_EQ(session.views.size(), 1u);
  const auto clouds = bag_clouds(bag, "/lidar_points");
  ASSERT_EQ(clouds.size(), 2u);
  const cloud::LoadedCloud loaded = cloud::load_pcd(session.views[0].cloud);
  // Both sweeps of the bag, their returns only; PROVENANCE.md: ~62k of 64k points per sweep.
  EXPECT_EQ(loaded.cloud->size(), clouds[0].finite + clouds[1].finite);
  EXPECT_GT(clouds[0].finite, 60000u);
  EXPECT_LT(clouds[0].finite, 64000u);
  EXPECT_TRUE(loaded.has_intensity);
  EXPECT_TRUE(loaded.has_ring);
  EXPECT_TRUE(loaded.has_t);
  float t_max = 0;
  for (const auto& p : *loaded.cloud) {
    EXPECT_LT(p.ring, 16);
    t_max = std::max(t_max, p.t);
  }
  // Two sweeps 0.1 s apart, each ~0.1 s long.
  EXPECT_GT(t_max, 0.1f);
  EXPECT_LT(t_max, 0.3f);
  EXPECT_TRUE(core::preflight_problems(session).empty());
  // The LIDAR's frame_id as the recording's driver set it, for rgbdt_calibrate's ROS outputs.
  EXPECT_NE(test_util::read_text(out / "frames.yaml").find("\nlidar: hesai_lidar\n"), std::string::npos);
}

TEST(ImportRealBag, MappingKindWritesOneCloudPerMessage) {
  const fs::path bag = board_bag("mid");
  const fs::path out = test::temp_path("session");
  const AppRun run =
      run_import(bag.string() + " --out " + out.string() + " --kind mapping --lidar /lidar_points",
                 out.string() + ".log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const core::MappingSession session = core::read_mapping_session(out.string());
  EXPECT_TRUE(session.cameras.empty());
  const auto index = core::read_time_index(session.lidar.clouds);
  const auto clouds = bag_clouds(bag, "/lidar_points");
  ASSERT_EQ(index.size(), clouds.size());
  for (std::size_t i = 0; i < index.size(); ++i) {
    const cloud::LoadedCloud loaded = cloud::load_pcd(index[i].file);
    EXPECT_EQ(loaded.cloud->size(), clouds[i].finite) << "cloud " << i;
    // The index stamps a cloud at its earliest point; double seconds near 1.8e9 keep ~0.2 us.
    EXPECT_NEAR(index[i].time_s, clouds[i].first_time_ns * 1e-9, 1e-6) << "cloud " << i;
  }
  EXPECT_TRUE(core::preflight_problems(session).empty());
  EXPECT_NE(test_util::read_text(out / "frames.yaml").find("\nlidar: hesai_lidar\n"), std::string::npos);
}

TEST(ImportErrors, MissingTopicExitsNonZeroNamingTopicAndBagAndLeavesNothing) {
  const fs::path bag = board_bag("left");
  const fs::path out = test::temp_path("session");
  const AppRun run = run_import(
      bag.string() + " --out " + out.string() + " --kind mapping --lidar /no_such_points",
      out.string() + ".log");
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_LT(run.exit_code, 128) << run.output;
  EXPECT_NE(run.output.find("/no_such_points"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("left_short.bag"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("/lidar_points"), std::string::npos)
      << "lists what the bag holds: " << run.output;
  EXPECT_FALSE(fs::exists(out));
  for (const auto& entry : fs::directory_iterator(out.parent_path())) {
    EXPECT_EQ(entry.path().filename().string().find("." + out.filename().string()),
              std::string::npos)
        << "left behind: " << entry.path();
  }
}

TEST(ImportErrors, WrongTypeNamesTopicAndType) {
  const fs::path out = test::temp_path("session");
  const AppRun run =
      run_import(board_bag("left").string() + " --out " + out.string() +
                     " --kind mapping --lidar /lidar_points --camera rgb=/lidar_points",
                 out.string() + ".log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(
      run.output.find("camera rgb image topic /lidar_points has type sensor_msgs/PointCloud2"),
      std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(ImportErrors, ExistingSessionIsNotOverwritten) {
  const fs::path out = test::temp_dir("session");
  test::write_text(out / "session.yaml", "keep me\n");
  const AppRun run = run_import(board_bag("left").string() + " --out " + out.string() +
                                    " --kind mapping --lidar /lidar_points",
                                out.string() + ".log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("not an empty folder"), std::string::npos) << run.output;
  std::ifstream f(out / "session.yaml");
  std::string line;
  std::getline(f, line);
  EXPECT_EQ(line, "keep me");
}

TEST(ImportErrors, CalibrationWithoutTargetIsRefused) {
  const fs::path out = test::temp_path("session");
  const AppRun run = run_import(board_bag("left").string() + " --out " + out.string() +
                                    " --kind calibration --lidar /lidar_points",
                                out.string() + ".log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("--target"), std::string::npos) << run.output;
}

// Two bags: the real board bag (left) as the calibration and a second real board bag (right)
// as the mapping, into OUT/calibration and OUT/mapping with the same topics.
TEST(ImportTwoBags, WriteTheCalibrationAndTheMappingSession) {
  const fs::path out = test::temp_path("rig");
  const AppRun run = run_import(board_bag("left").string() + " " + board_bag("right").string() +
                                    " --out " + out.string() + " --lidar /lidar_points --target " +
                                    kBoardTarget,
                                out.string() + ".log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const core::CalibrationSession calibration =
      core::read_calibration_session((out / "calibration").string());
  EXPECT_EQ(calibration.views.size(), 1u);
  const core::MappingSession mapping = core::read_mapping_session((out / "mapping").string());
  const auto clouds = core::read_time_index(mapping.lidar.clouds);
  EXPECT_EQ(clouds.size(), bag_clouds(board_bag("right"), "/lidar_points").size());
  EXPECT_TRUE(core::preflight_problems(calibration).empty());
  EXPECT_TRUE(core::preflight_problems(mapping).empty());
}

// When the second bag cannot be read, the first bag's finished session goes too: a run leaves
// both sessions or neither (and no OUT it made itself).
TEST(ImportTwoBags, ASecondBagThatFailsLeavesNeitherSession) {
  const fs::path dir = test::temp_dir("two");
  const fs::path not_a_bag = dir / "drive.bag", out = dir / "rig";
  test::write_text(not_a_bag, "not a bag\n");
  AppRun run = run_import(board_bag("left").string() + " " + not_a_bag.string() + " --out " +
                              out.string() + " --lidar /lidar_points --target " + kBoardTarget,
                          dir / "run.log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("drive.bag"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("no session was written"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(out)) << run.output;
  // An empty OUT given by the user stays, empty.
  fs::create_directories(out);
  run = run_import(board_bag("left").string() + " " + not_a_bag.string() + " --out " +
                       out.string() + " --lidar /lidar_points --target " + kBoardTarget,
                   dir / "run2.log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(fs::is_directory(out) && fs::is_empty(out)) << run.output;
  // A second bag that does not exist is found before the first is read.
  run = run_import(board_bag("left").string() + " " + (dir / "nothere.bag").string() + " --out " +
                       (dir / "rig2").string() + " --lidar /lidar_points --target " + kBoardTarget,
                   dir / "run3.log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("nothere.bag: does not exist"), std::string::npos) << run.output;
  EXPECT_EQ(run.output.find("kept as view"), std::string::npos) << run.output;
}

TEST(ImportTwoBags, KindTimeWindowAndMissingTargetAreRefused) {
  const std::string bags = board_bag("left").string() + " " + board_bag("right").string();
  const fs::path out = test::temp_path("rig");
  for (const auto& [extra, option] :
       {std::pair{std::string(" --kind mapping --target ") + kBoardTarget, "--kind"},
        std::pair{std::string(" --start 1 --target ") + kBoardTarget, "--start"},
        std::pair{std::string(""), "--target"}}) {
    const AppRun run = run_import(bags + " --out " + out.string() + " --lidar /lidar_points" + extra,
                                  out.string() + ".log");
    EXPECT_NE(run.exit_code, 0) << run.output;
    EXPECT_LT(run.exit_code, 128) << run.output;
    EXPECT_NE(run.output.find(option), std::string::npos) << run.output;
    EXPECT_FALSE(fs::exists(out)) << run.output;
  }
}

TEST(ImportHelp, ExplainsEveryOptionWithAnExample) {
  const AppRun run = run_import("--help", test::temp_path("help.log"));
  EXPECT_EQ(run.exit_code, 0);
  for (const char* option :
       {"--out", "--kind", "--lidar", "--camera", "--camera-info", "--intrinsics", "--radiometry",
        "--imu", "rgbdt_import board.bag drive.bag", "OUT/calibration",
        "--start", "--end", "--target", "--still-threshold", "--min-still-frames", "--still-camera",
        "--max-view-points", "Examples:", "rgbdt_import run.mcap"}) {
    EXPECT_NE(run.output.find(option), std::string::npos) << option;
  }
}

// ---------------------------------------------------------------------------------------
// Still intervals in a ROS 1 bag written with rosbag::Bag: a 10 fps camera whose frames are
// still for 8 frames, move for 3, are still for 6, move, then still for 3 (too short).

cv::Mat scene(int shift_px) {
  cv::Mat image(120, 160, CV_8UC3, cv::Scalar(40, 40, 40));
  cv::rectangle(image, cv::Rect(30 + shift_px, 30, 50, 40), cv::Scalar(220, 200, 180), cv::FILLED);
  cv::circle(image, cv::Point(100 + shift_px, 80), 15, cv::Scalar(0, 0, 255), cv::FILLED);
  return image;
}

sensor_msgs::Image to_ros1_image(const cv::Mat& bgr, const ros::Time& stamp) {
  sensor_msgs::Image m;
  m.header.stamp = stamp;
  m.header.frame_id = "camera";
  m.height = static_cast<std::uint32_t>(bgr.rows);
  m.width = static_cast<std::uint32_t>(bgr.cols);
  m.encoding = "bgr8";
  m.step = static_cast<std::uint32_t>(bgr.cols * 3);
  m.data.assign(bgr.data, bgr.data + bgr.total() * 3);
  return m;
}

sensor_msgs::PointCloud2 ros1_cloud(std::uint32_t points, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 c;
  c.header.stamp = stamp;
  c.header.frame_id = "lidar";
  c.height = 1;
  c.width = points;
  for (const char* name : {"x", "y", "z"}) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = static_cast<std::uint32_t>(4 * c.fields.size());
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    c.fields.push_back(f);
  }
  c.point_step = 12;
  c.row_step = 12 * points;
  c.data.resize(c.row_step);
  for (std::uint32_t i = 0; i < points; ++i) {
    const float xyz[3] = {4.0f, 0.01f * i, 0.5f};
    std::memcpy(c.data.data() + 12 * i, xyz, 12);
  }
  c.is_dense = true;
  return c;
}

sensor_msgs::CameraInfo ros1_camera_info(const ros::Time& stamp) {
  sensor_msgs::CameraInfo info;
  info.header.stamp = stamp;
  info.width = 160;
  info.height = 120;
  info.distortion_model = "plumb_bob";
  info.D = {0.1, -0.05, 0, 0, 0};
  info.K = {150, 0, 80, 0, 150, 60, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {150, 0, 80, 0, 0, 150, 60, 0, 0, 0, 1, 0};
  return info;
}

// Frame k's shift: still runs at frames 0-7 (shift 0), 11-16 (shift 40), 19-21 (shift 20);
// moving frames in between.
int shift_of(int k) {
  if (k <= 7) return 0;
  if (k <= 10) return 10 * (k - 7);
  if (k <= 16) return 40;
  if (k <= 18) return 40 - 7 * (k - 16);
  return 20;
}
constexpr int kFrames = 22;

// Frames at 10 fps from t = 1000 s, a cloud of 100 + k points at every frame time + 0.05 s.
fs::path write_still_bag(const fs::path& path) {
  fs::create_directories(path.parent_path());
  rosbag::Bag bag(path.string(), rosbag::bagmode::Write);
  for (int k = 0; k < kFrames; ++k) {
    const ros::Time t(1000.0 + 0.1 * k);
    const ros::Time tc(1000.05 + 0.1 * k);
    bag.write("/cam/image_raw", t, to_ros1_image(scene(shift_of(k)), t));
    if (k == 0) bag.write("/cam/camera_info", t, ros1_camera_info(t));
    bag.write("/points", tc, ros1_cloud(100 + k, tc));
  }
  bag.close();
  return path;
}

TEST(ImportStillIntervals, KeepsLongStillRunsWithTheirCloudsAndMiddleFrames) {
  const fs::path dir = test::temp_dir("work");
  const fs::path bag = write_still_bag(dir / "still.bag");
  const fs::path out = dir / "session";
  const AppRun run =
      run_import(bag.string() + " --out " + out.string() +
                     " --kind calibration --lidar /points --camera rgb=/cam/image_raw "
                     "--target '{type: circle_hole, radius: 0.3}'",
                 dir / "import.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("kept as view 000"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("kept as view 001"), std::string::npos) << run.output;
  EXPECT_EQ(run.output.find("kept as view 002"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("fewer than --min-still-frames 5"), std::string::npos) << run.output;

  const core::CalibrationSession session = core::read_calibration_session(out.string());
  ASSERT_EQ(session.views.size(), 2u);
  EXPECT_TRUE(core::preflight_problems(session).empty());
  const core::CameraIntrinsics in = core::read_camera_info(session.cameras.at("rgb").intrinsics);
  EXPECT_EQ(in.fx, 150.0);
  EXPECT_EQ(in.width, 160);
  EXPECT_EQ(in.distortion[0], 0.1);
  // View 0: frames 0-7 (1000.0 - 1000.7 s) hold the clouds of frames 0-6 (at +0.05 s);
  // view 1: frames 11-16 hold the clouds of frames 11-15.
  const struct { int first, last, middle_frame; } expected[] = {{0, 6, 4}, {11, 15, 14}};
  for (int v = 0; v < 2; ++v) {
    std::size_t points = 0;
    for (int k = expected[v].first; k <= expected[v].last; ++k) points += 100 + k;
    EXPECT_EQ(cloud::load_pcd(session.views[v].cloud).cloud->size(), points) << "view " << v;
    const cv::Mat image = cv::imread(session.views[v].images.at("rgb"), cv::IMREAD_UNCHANGED);
    const cv::Mat truth = scene(shift_of(expected[v].middle_frame));
    ASSERT_EQ(image.size(), truth.size());
    EXPECT_EQ(cv::norm(image, truth, cv::NORM_INF), 0.0) << "view " << v;
  }
  // The bag's frame_ids, for rgbdt_calibrate's ROS outputs.
  const std::string frames = test_util::read_text(out / "frames.yaml");
  EXPECT_NE(frames.find("\nlidar: lidar\n"), std::string::npos) << frames;
  EXPECT_NE(frames.find("\nrgb: camera\n"), std::string::npos) << frames;
}

TEST(ImportStillIntervals, MissingCameraInfoNamesTheSiblingTopic) {
  const fs::path dir = test::temp_dir("work");
  const fs::path bag = write_still_bag(dir / "still.bag");
  const AppRun run =
      run_import(bag.string() + " --out " + (dir / "session").string() +
                     " --kind mapping --lidar /points --camera rgb=/other/image_raw/compressed",
                 dir / "import.log");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("/other/image_raw/compressed is not in the bag"), std::string::npos)
      << run.output;
}

// --radiometry: written to session.yaml as given; a bad one is refused naming the option, the
// camera and the fault, before the bag is read.
TEST(ImportRadiometry, IsWrittenAsGivenAndABadOneIsRefused) {
  const fs::path dir = test::temp_dir("work");
  const fs::path bag = write_still_bag(dir / "still.bag");
  const fs::path out = dir / "session";
  AppRun run = run_import(bag.string() + " --out " + out.string() +
                              " --kind mapping --lidar /points --camera "
                              "thermal=/cam/image_raw --radiometry 'thermal={type: planck, "
                              "R: 366545, B: 1428, F: 1, O: -342}'",
                          out.string() + ".log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const core::MappingSession session = core::read_mapping_session(out.string());
  const auto& radiometry = session.cameras.at("thermal").radiometry;
  ASSERT_TRUE(radiometry.has_value());
  EXPECT_EQ(radiometry->type, "planck");
  EXPECT_EQ(radiometry->parameters,
            (std::map<std::string, double>{{"R", 366545}, {"B", 1428}, {"F", 1}, {"O", -342}}));
  for (const auto& [spec, fault] :
       {std::pair{"thermal={type: linear, kelvin_per_count: -3}", "kelvin_per_count"},
        std::pair{"thermal={type: plank, R: 1}", "unknown type 'plank'"},
        std::pair{"thermal={type: linear, kelvin_per_count: 0.1", "is not a YAML map"},
        std::pair{"rgb={type: linear, kelvin_per_count: 0.1}", "camera rgb is not named"}}) {
    const fs::path bad = test::temp_path("bad");
    run = run_import(bag.string() + " --out " + bad.string() +
                         " --kind mapping --lidar /points --camera "
                         "thermal=/cam/image_raw --radiometry '" + spec + "'",
                     bad.string() + ".log");
    EXPECT_NE(run.exit_code, 0) << spec;
    EXPECT_LT(run.exit_code, 128) << spec;
    EXPECT_NE(run.output.find("--radiometry"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find(fault), std::string::npos) << run.output;
    EXPECT_FALSE(fs::exists(bad));
  }
}

// ---------------------------------------------------------------------------------------
// A simulated mapping session written to a ROS 1 bag by the real ROS 1 Python libraries
// (tests/fixtures/write_ros1_bag.py), imported back: the same points and pixels.

TEST(ImportRos1Fixture, SimMappingSessionRoundTripsThroughARos1Bag) {
  const fs::path dir = test::temp_dir("work");
  const fs::path sim = dir / "sim", bag = dir / "sim.bag", out = dir / "imported";
  // 1.5 s: two tilts (0.6 s each), three frames per camera; supersampling 1 for speed.
  test_util::CommandRun run =
      test_util::run_command(test::built_program("rgbdt_sim") + " mapping --out " + sim.string() +
                                 " --duration 1.5 --rgb-fps 2 --thermal-fps 2 --supersampling 1 -q",
                             dir / "sim.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  run = test_util::run_command(
      test_util::ros1_fixture("write_ros1_bag.py") + " " + sim.string() + " " + bag.string(),
      dir / "fixture.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const AppRun imported =
      run_import(bag.string() + " --out " + out.string() +
                     " --kind mapping --lidar /lidar/points --camera rgb=/rgb/image_raw"
                     " --camera thermal=/thermal/image_raw",
                 dir / "import.log");
  ASSERT_EQ(imported.exit_code, 0) << imported.output;

  test_util::expect_same_mapping_session(sim.string(), out.string());
}

// ---------------------------------------------------------------------------------------
// The parts on their own.

TEST(SplitRuns, FramesJoinTheRunOfTheFrameBeforeWhenTheyDifferLittle) {
  const auto runs = split_runs({0, 1, 1, 9, 1, 9, 9, 0.5}, 2.0);
  ASSERT_EQ(runs.size(), 4u);
  EXPECT_EQ(runs[0].first, 0u);
  EXPECT_EQ(runs[0].last, 2u);
  EXPECT_EQ(runs[1].first, 3u);
  EXPECT_EQ(runs[1].last, 4u);
  EXPECT_EQ(runs[2].frames(), 1u);
  EXPECT_EQ(runs[3].first, 6u);
  EXPECT_EQ(runs[3].last, 7u);
  EXPECT_TRUE(split_runs({}, 1.0).empty());
}

TEST(FrameDifference, NoiseIsStillAndAShiftedBoardIsNot) {
  // 640x480 frames: downscaled 4x to 160 px wide, so pixel noise averages over 16 pixels.
  const auto large = [](const cv::Mat& image) {
    cv::Mat out;
    cv::resize(image, out, cv::Size(640, 480), 0, 0, cv::INTER_NEAREST);
    return out;
  };
  FrameDifference difference;
  cv::Mat noise(480, 640, CV_32FC3);
  cv::randn(noise, 0, 4);  // sensor noise of sigma 4 grey levels
  cv::Mat with_noise;
  cv::add(large(scene(0)), noise, with_noise, cv::noArray(), CV_8UC3);
  EXPECT_FALSE(difference.add(large(scene(0))).has_value());
  // Mean |noise| of 16-pixel averages of grey noise (sigma ~ 4 / 4): ~0.8.
  EXPECT_LT(*difference.add(with_noise), 2.0);
  EXPECT_GT(*difference.add(large(scene(10))), 5.0);
}

TEST(FrameDifference, SixteenBitFramesAreScaledByTheFirstFramesRange) {
  FrameDifference difference;
  cv::Mat a(64, 80, CV_16UC1, cv::Scalar(8000));
  cv::rectangle(a, cv::Rect(10, 10, 20, 20), cv::Scalar(9000), cv::FILLED);
  cv::Mat b(64, 80, CV_16UC1, cv::Scalar(8000));
  cv::rectangle(b, cv::Rect(40, 30, 20, 20), cv::Scalar(9000), cv::FILLED);
  difference.add(a);
  EXPECT_EQ(*difference.add(a), 0.0);
  // Two 20x20 squares of 255 levels moved over an 80x64 frame: 2 * 400 * 255 / 5120 = 39.8.
  EXPECT_NEAR(*difference.add(b), 39.8, 2.0);
}

const bag::MessageContext kContext{"/cam", 2, 0, bag::Serialization::kRos1};

TEST(Convert, ColourOrdersBayerAndBigEndianSixteenBit) {
  bag::Image rgb;
  rgb.width = 2;
  rgb.height = 1;
  rgb.encoding = "rgb8";
  rgb.step = 8;  // 2 bytes of row padding
  rgb.data = {10, 20, 30, 40, 50, 60, 0, 0};
  const cv::Mat bgr = image_to_mat(rgb, kContext);
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 1), cv::Vec3b(60, 50, 40));

  bag::Image mono16;
  mono16.width = 1;
  mono16.height = 1;
  mono16.encoding = "mono16";
  mono16.is_bigendian = 1;
  mono16.step = 2;
  mono16.data = {0x12, 0x34};
  EXPECT_EQ(image_to_mat(mono16, kContext).at<std::uint16_t>(0, 0), 0x1234);

  bag::Image bayer;
  bayer.width = 4;
  bayer.height = 4;
  bayer.encoding = "bayer_rggb8";
  bayer.step = 4;
  // Red at even rows and columns only: the demosaiced centre is red.
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) bayer.data.push_back(r % 2 == 0 && c % 2 == 0 ? 200 : 0);
  const cv::Vec3b centre = image_to_mat(bayer, kContext).at<cv::Vec3b>(2, 2);
  EXPECT_GT(centre[2], 100);
  EXPECT_EQ(centre[0], 0);
}

TEST(Convert, BadImagesThrowNamingTheTopic) {
  bag::Image image;
  image.width = 4;
  image.height = 2;
  image.encoding = "mono8";
  image.step = 3;  // smaller than a row
  image.data.assign(8, 0);
  test::expect_error_mentions<core::Error>([&] { image_to_mat(image, kContext); },
                                           {"/cam", "step 3"});
  image.step = 4;
  image.data.assign(7, 0);
  test::expect_error_mentions<core::Error>([&] { image_to_mat(image, kContext); },
                                           {"/cam", "7 bytes"});
  image.encoding = "yuv422";
  test::expect_error_mentions<core::Error>([&] { image_to_mat(image, kContext); },
                                           {"/cam", "yuv422"});
  bag::CompressedImage depth;
  depth.format = "16UC1; compressedDepth";
  depth.data = {1, 2, 3};
  test::expect_error_mentions<core::Error>([&] { compressed_to_mat(depth, kContext); },
                                           {"/cam", "compressedDepth"});
  bag::CompressedImage junk;
  junk.format = "jpeg";
  junk.data = {1, 2, 3};
  test::expect_error_mentions<core::Error>([&] { compressed_to_mat(junk, kContext); },
                                           {"/cam", "does not decode"});
}

TEST(Convert, PcdKeepsOnlyTheChannelsTheCloudHasAndRoundTrips) {
  bag::CloudPoints points;
  points.xyz = {{1, 2, 3}, {NAN, 0, 0}, {4, 5, 6}, {0, 0, 0}};
  points.ring = {3, 4, 5, 6};
  points.time_ns = {2000000000, 1000000000, 2500000000, 500000000};
  const PcdCloud cloud = to_pcd_cloud(points, 0);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.first_time_ns, 2000000000);  // dropped points' times do not count
  const fs::path path = test::temp_dir("pcd") / "c.pcd";
  std::ofstream(path, std::ios::binary) << format_pcd(cloud);
  const cloud::LoadedCloud loaded = cloud::load_pcd(path.string());
  EXPECT_FALSE(loaded.has_intensity);
  EXPECT_TRUE(loaded.has_ring);
  EXPECT_TRUE(loaded.has_t);
  ASSERT_EQ(loaded.cloud->size(), 2u);
  EXPECT_EQ(loaded.cloud->points[1].x, 4.0f);
  EXPECT_EQ(loaded.cloud->points[1].ring, 5);
  EXPECT_FLOAT_EQ(loaded.cloud->points[1].t, 0.5f);
}

}  // namespace
}  // namespace rgbdt::import
