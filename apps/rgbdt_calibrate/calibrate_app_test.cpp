// rgbdt_calibrate as a user runs it: exit codes and messages.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/transform.hpp"

namespace {

namespace fs = std::filesystem;

std::string bin_dir() {
  const char* dir = std::getenv("RGBDT_BIN_DIR");
  return dir ? dir : std::string(RGBDT_BINARY_DIR) + "/bin";
}

struct AppRun {
  int exit_code;
  std::string output;
};

AppRun run_app(const std::string& args) {
  // One log per test: ctest runs the tests of this file as parallel processes.
  const fs::path log_dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "rgbdt_calibrate_logs";
  fs::create_directories(log_dir);
  const std::string log =
      (log_dir / (std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + ".log")).string();
  const int status = std::system((bin_dir() + "/rgbdt_calibrate " + args + " > " + log + " 2>&1").c_str());
  std::ifstream f(log);
  std::stringstream ss;
  ss << f.rdbuf();
  return {WEXITSTATUS(status), ss.str()};
}

// A session of a wall with no target: a flat LIDAR plane and uniform grey images.
std::string write_session_without_target(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "clouds");
  fs::create_directories(dir / "rgb");
  rgbdt::core::CameraIntrinsics in;
  in.camera_name = "rgb";
  in.width = 640;
  in.height = 480;
  in.fx = in.fy = 600.0;
  in.cx = 320.0;
  in.cy = 240.0;
  in.distortion = {0, 0, 0, 0, 0};
  rgbdt::core::write_camera_info((dir / "rgb.yaml").string(), in);
  rgbdt::core::CalibrationSession session;
  session.target.radius_m = 0.3;
  session.cameras["rgb"].intrinsics = (dir / "rgb.yaml").string();
  for (int v = 0; v < 2; ++v) {
    rgbdt::cloud::Cloud wall;
    for (int r = 0; r < 60; ++r)
      for (int c = 0; c < 200; ++c) {
        rgbdt::cloud::PointXYZIRT p;
        p.x = 5.0f;
        p.y = -2.0f + 0.02f * c;
        p.z = -0.6f + 0.02f * r;
        p.ring = static_cast<std::uint16_t>(r);
        wall.push_back(p);
      }
    const std::string cloud = (dir / "clouds" / (std::to_string(v) + ".pcd")).string();
    const std::string image = (dir / "rgb" / (std::to_string(v) + ".png")).string();
    rgbdt::cloud::save_pcd(cloud, wall);
    cv::imwrite(image, cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
    rgbdt::core::CalibrationView view;
    view.cloud = cloud;
    view.images["rgb"] = image;
    session.views.push_back(view);
  }
  rgbdt::core::write_calibration_session((dir / "session.yaml").string(), session);
  return dir.string();
}

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// A simulated session (rgb and thermal, one-hole board) of `views` views, in its own folder
// per test.
std::string simulate_session(const std::string& name, int views = 3, const std::string& extra = "") {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());  // the .sim.log goes beside it
  const std::string cmd = bin_dir() + "/rgbdt_sim calibration --views " + std::to_string(views) + " --seed 1 " + extra + " --out " +
                          dir.string() + " > " + dir.string() + ".sim.log 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return dir.string();
}

TEST(RgbdtCalibrate, HelpExplainsItselfAndExitsZero) {
  const AppRun r = run_app("--help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("SESSION_DIR"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--method"), std::string::npos) << r.output;
}

TEST(RgbdtCalibrate, SessionWhoseTargetIsNeverFoundFailsWithAClearError) {
  const std::string session = write_session_without_target("rgbdt_calibrate_no_target");
  const std::string out = session + "/out";
  const AppRun r = run_app(session + " --out " + out);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("target was never found"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_rgb.yaml"));
}

TEST(RgbdtCalibrate, MissingSessionNamesTheFile) {
  const AppRun r = run_app("/nonexistent/session --out " + (fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "rgbdt_calibrate_none").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("/nonexistent/session"), std::string::npos) << r.output;
}

// The default seeds (a LIDAR seed on the board beside the hole, behind it a larger cloth)
// find the board: the seeded plane is cut to the part that holds the seed.
TEST(RgbdtCalibrate, SimulatedSessionCalibratesWithTheDefaultSeeds) {
  const std::string session = simulate_session("rgbdt_calibrate_default_seeds");
  const std::string out = session + "/out";
  const AppRun r = run_app(session + " --out " + out);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_thermal.yaml")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/report.md")) << r.output;
  EXPECT_EQ(r.output.find("not found"), std::string::npos) << r.output;
}

// Seeds are hints: a LIDAR seed far from any surface falls back to the automatic
// detection, which finds the board, and the report says so.
TEST(RgbdtCalibrate, AFailedSeedFallsBackToTheAutomaticDetectionAndSaysSo) {
  const std::string dir = simulate_session("rgbdt_calibrate_bad_seed");
  rgbdt::core::CalibrationSession s = rgbdt::core::read_calibration_session(dir);
  for (auto& v : s.views) v.lidar_seed = Eigen::Vector3d(0.0, 0.0, 40.0);
  rgbdt::core::write_calibration_session(dir + "/session.yaml", s);
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --camera rgb");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  const std::string report = read_text(out + "/report.md");
  EXPECT_NE(report.find("view 0: LIDAR seed: seeded detection failed (no points near the seed"), std::string::npos)
      << report;
  EXPECT_NE(report.find("the automatic detection found the target"), std::string::npos) << report;
  // The report ends with the options the run used, as --config reads them.
  EXPECT_NE(report.find("## Configuration"), std::string::npos) << report;
  EXPECT_NE(report.find("camera: rgb\nmethod: edge\n"), std::string::npos) << report;
}

// The thermal camera's intrinsics with twice its focal lengths: its images then fit the
// LIDAR only with the board about twice as far from it, a camera metres from the LIDAR,
// which the verdict FAILs (--max-translation, 2 m). (A guess turned away from the board is
// no reliable failure: the hole-centre stage brings the solve back from it.)
void break_thermal_intrinsics(const std::string& session) {
  rgbdt::core::CameraIntrinsics k = rgbdt::core::read_camera_info(session + "/thermal.yaml");
  k.fx *= 2.0;
  k.fy *= 2.0;
  rgbdt::core::write_camera_info(session + "/thermal.yaml", k);
}

// One camera that cannot be calibrated (break_thermal_intrinsics) is reported by name with
// its reason; the other camera is still written, and report.md marks the run complete.
// Nothing is written for the failed camera.
TEST(RgbdtCalibrate, AFailingCameraIsReportedAndTheOthersAreWritten) {
  const std::string session = simulate_session("rgbdt_calibrate_one_fails");
  const std::string out = session + "/out";
  break_thermal_intrinsics(session);
  const AppRun r = run_app(session + " --out " + out + " --seeds none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/overlay_rgb_000.jpg")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_thermal.yaml")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_thermal_rgb.yaml")) << r.output;
  EXPECT_NE(r.output.find("error: camera thermal: not calibrated: "), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(out + "/report.md")) << r.output;
  const std::string report = read_text(out + "/report.md");
  EXPECT_NE(report.find("**FAILED for 1 of 2 camera(s)**"), std::string::npos) << report;
  EXPECT_NE(report.find("- **thermal**: "), std::string::npos) << report;
  // The ROS outputs hold the calibrated camera only, in the default frames.
  const std::string launch = read_text(out + "/static_transforms.launch.py");
  EXPECT_NE(launch.find("'--frame-id', 'lidar', '--child-frame-id', 'rgb'"), std::string::npos)
      << launch;
  EXPECT_EQ(launch.find("thermal"), std::string::npos) << launch;
  const std::string urdf = read_text(out + "/urdf_joints.xml");
  EXPECT_NE(urdf.find("<child link=\"rgb\"/>"), std::string::npos) << urdf;
  EXPECT_EQ(urdf.find("thermal"), std::string::npos) << urdf;
}

// The numbers of one --flag in the launch file's arguments of the Node whose child frame is
// `child`: e.g. "'--x', '0.123'".
double launch_argument(const std::string& launch, const std::string& child,
                       const std::string& flag) {
  const size_t end = launch.find("'--child-frame-id', '" + child + "'");
  if (end == std::string::npos) {
    ADD_FAILURE() << "no node with child frame " << child << " in\n" << launch;
    return 0.0;
  }
  const size_t begin = launch.rfind("Node(", end);
  const std::string node = launch.substr(begin, end - begin);
  std::smatch m;
  if (!std::regex_search(node, m, std::regex("'" + flag + "', '([^']+)'"))) {
    ADD_FAILURE() << "no " << flag << " in\n" << node;
    return 0.0;
  }
  return std::stod(m[1]);
}

// static_transforms.launch.py and urdf_joints.xml hold T_lidar_camera, the inverse of the
// YAML's T_camera_lidar, in the frames of --frames; a FAILed camera is in neither. Python
// parses the launch file, and the URDF is well-formed XML.
TEST(RgbdtCalibrate, RosOutputsHoldTheInverseOfTheYamlInTheGivenFrames) {
  const std::string session = simulate_session("rgbdt_calibrate_ros_outputs");
  const std::string out = session + "/out";
  break_thermal_intrinsics(session);
  const AppRun bad = run_app(session + " --out " + out + " --frames lidar=velodyne,left=cam");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("--frames: 'left' is neither lidar nor a camera of the session"),
            std::string::npos)
      << bad.output;
  const AppRun r =
      run_app(session + " --out " + out +
              " --seeds none --frames lidar=velodyne,rgb=camera_rgb_optical_frame,thermal=flir_link");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  ASSERT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  ASSERT_FALSE(fs::exists(out + "/extrinsics_thermal.yaml")) << r.output;
  const Eigen::Isometry3d T_lidar_camera =
      rgbdt::core::read_extrinsics(out + "/extrinsics_rgb.yaml").T_parent_child.inverse();

  const std::string launch_path = out + "/static_transforms.launch.py";
  const std::string launch = read_text(launch_path);
  EXPECT_NE(launch.find("package='tf2_ros'"), std::string::npos) << launch;
  EXPECT_NE(launch.find("executable='static_transform_publisher'"), std::string::npos) << launch;
  EXPECT_NE(launch.find("'--frame-id', 'velodyne', '--child-frame-id', 'camera_rgb_optical_frame'"),
            std::string::npos)
      << launch;
  EXPECT_EQ(launch.find("flir_link"), std::string::npos) << launch;
  EXPECT_EQ(launch.find("thermal"), std::string::npos) << launch;
  const std::string child = "camera_rgb_optical_frame";
  const Eigen::Vector3d t(launch_argument(launch, child, "--x"),
                          launch_argument(launch, child, "--y"),
                          launch_argument(launch, child, "--z"));
  const Eigen::Quaterniond q(
      launch_argument(launch, child, "--qw"), launch_argument(launch, child, "--qx"),
      launch_argument(launch, child, "--qy"), launch_argument(launch, child, "--qz"));
  EXPECT_LT((t - T_lidar_camera.translation()).norm(), 1e-6) << launch;
  EXPECT_NEAR(q.norm(), 1.0, 1e-6);
  EXPECT_LT((q.toRotationMatrix() - T_lidar_camera.linear()).cwiseAbs().maxCoeff(), 1e-6) << launch;
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  EXPECT_EQ(
      std::system(
          (python + " -c \"import ast; ast.parse(open('" + launch_path + "').read())\"").c_str()),
      0)
      << launch;

  const std::string urdf_path = out + "/urdf_joints.xml";
  const std::string urdf = read_text(urdf_path);
  EXPECT_EQ(std::system(
                (python + " -c \"import xml.etree.ElementTree as E; E.parse('" + urdf_path + "')\"")
                    .c_str()),
            0)
      << urdf;
  EXPECT_EQ(urdf.find("flir_link"), std::string::npos) << urdf;
  std::smatch m;
  const std::regex joint(
      "<joint name=\"[^\"]+\" type=\"fixed\">\\s*<parent link=\"velodyne\"/>\\s*<child "
      "link=\"camera_rgb_optical_frame\"/>\\s*<origin xyz=\"(\\S+) (\\S+) (\\S+)\" rpy=\"(\\S+) "
      "(\\S+) (\\S+)\"/>");
  ASSERT_TRUE(std::regex_search(urdf, m, joint)) << urdf;
  const Eigen::Vector3d xyz(std::stod(m[1]), std::stod(m[2]), std::stod(m[3]));
  const Eigen::Matrix3d R =
      rgbdt::core::rotation_from_rpy(std::stod(m[4]), std::stod(m[5]), std::stod(m[6]));
  EXPECT_LT((xyz - T_lidar_camera.translation()).norm(), 1e-6) << urdf;
  EXPECT_LT((R - T_lidar_camera.linear()).cwiseAbs().maxCoeff(), 1e-6) << urdf;
  size_t joints = 0;
  for (size_t p = urdf.find("<joint "); p != std::string::npos; p = urdf.find("<joint ", p + 1))
    ++joints;
  EXPECT_EQ(joints, 1u) << urdf;
}

// A session's frames.yaml (rgbdt_import writes it from the bag's frame_ids) names the frames
// of the ROS outputs; --frames overrides it key by key. A frames.yaml naming no sensor of the
// session is an error naming the file and the key.
TEST(RgbdtCalibrate, TheSessionsFramesYamlNamesTheRosFramesUnderFrames) {
  const std::string session = simulate_session("rgbdt_calibrate_frames_yaml");
  const std::string out = session + "/out";
  { std::ofstream(session + "/frames.yaml") << "lidar: os_sensor\nrgb: camera_color_optical_frame\nleft: cam\n"; }
  const AppRun bad = run_app(session + " --out " + out + " --camera rgb --seeds none");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find(session + "/frames.yaml: 'left' is neither lidar nor a camera of the session"),
            std::string::npos)
      << bad.output;
  { std::ofstream(session + "/frames.yaml") << "lidar: os_sensor\nrgb: camera_color_optical_frame\n"; }
  const AppRun r = run_app(session + " --out " + out + " --camera rgb --seeds none --frames lidar=base_lidar");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const std::string launch = read_text(out + "/static_transforms.launch.py");
  EXPECT_NE(launch.find("'--frame-id', 'base_lidar', '--child-frame-id', 'camera_color_optical_frame'"),
            std::string::npos)
      << launch;
  EXPECT_EQ(launch.find("os_sensor"), std::string::npos) << launch;
}

// A camera name far longer than any fixed buffer: the overlays carry the whole name.
TEST(RgbdtCalibrate, ALongCameraNameGivesWholeOverlayNames) {
  const std::string dir = simulate_session("rgbdt_calibrate_long_name");
  rgbdt::core::CalibrationSession s = rgbdt::core::read_calibration_session(dir);
  // 64 characters, the longest name session.yaml accepts; the overlay's file name is 80.
  const std::string name(64, 'c');
  s.cameras[name] = s.cameras.at("rgb");
  s.cameras.erase("rgb");
  for (auto& v : s.views) {
    v.images[name] = v.images.at("rgb");
    v.images.erase("rgb");
    v.image_seeds.clear();
  }
  rgbdt::core::write_calibration_session(dir + "/session.yaml", s);
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --camera " + name);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/overlay_" + name + "_000.jpg")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_" + name + ".yaml")) << r.output;
}

// Every missing or mismatched file is listed at once, before any detection runs.
TEST(RgbdtCalibrate, PreflightListsEveryProblemBeforeAnyDetection) {
  const std::string dir = simulate_session("rgbdt_calibrate_preflight");
  fs::remove(dir + "/clouds/001.pcd");
  fs::remove(dir + "/thermal/002.png");
  cv::imwrite(dir + "/rgb/000.png", cv::Mat(482, 644, CV_8U, cv::Scalar(90)));  // half size
  { std::ofstream(dir + "/rgb/002.png") << "not a png"; }
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output.find("detecting the target"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(dir + "/clouds/001.pcd: does not exist"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(dir + "/thermal/002.png: does not exist"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(dir + "/rgb/000.png: image is 644x482"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("says 1288x964"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(dir + "/rgb/002.png: is neither a PNG nor a JPEG"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out + "/report.md"));
}

// Ctrl-C during the detection: the app stops at the next view, exits 130 and leaves no
// report.md, neither this run's nor the stale one of an earlier run in the same folder.
TEST(RgbdtCalibrate, InterruptStopsWritesNoReportAndExits130) {
  const std::string dir = simulate_session("rgbdt_calibrate_interrupt");
  const std::string out = dir + "/out";
  fs::create_directories(out);
  { std::ofstream(out + "/report.md") << "# report of an earlier run\n"; }
  { std::ofstream(out + "/extrinsics_rgb.yaml") << "stale\n"; }
  // SIGINT once the app says it is detecting (its handler is installed by then).
  const std::string log = dir + ".run.log";
  const std::string cmd = "bash -c '" + bin_dir() + "/rgbdt_calibrate " + dir + " --out " + out + " > " + log +
                          " 2>&1 & pid=$!; for i in $(seq 600); do grep -q detecting " + log +
                          " && break; sleep 0.05; done; kill -INT $pid; wait $pid'";
  const int status = std::system(cmd.c_str());
  const std::string output = read_text(log);
  EXPECT_EQ(WEXITSTATUS(status), 130) << output;
  EXPECT_FALSE(fs::exists(out + "/report.md")) << output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_rgb.yaml")) << output;
  EXPECT_NE(output.find("interrupted"), std::string::npos) << output;
}

// The verdict: a consistent 10-view session passes and writes the extrinsics.
TEST(RgbdtCalibrate, TenSimulatedViewsPass) {
  const std::string dir = simulate_session("rgbdt_calibrate_verdict_pass", 10);
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --camera rgb --seeds none");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_rgb.rejected.yaml")) << r.output;
  EXPECT_EQ(r.output.find("FAIL"), std::string::npos) << r.output;
  // Each hole's LIDAR uncertainty from its detection goes into the covariance, so the
  // verdict's observability and leave-one-view-out checks judge by an honest one.
  EXPECT_NE(r.output.find("verdict: PASS"), std::string::npos) << r.output;
  const std::string report = read_text(out + "/report.md");
  EXPECT_NE(report.find("**Verdict: "), std::string::npos) << report;
  EXPECT_NE(report.find("| view | hole | lidar_x_m |"), std::string::npos) << report;
  EXPECT_TRUE(fs::exists(out + "/detections_rgb.csv")) << r.output;
}

// One view: usable, but the verdict warns and names the weakly constrained direction. (A
// 4-hole board: one view of one hole has no closed-form start, see align_edges.)
TEST(RgbdtCalibrate, OneViewWarnsAndNamesTheWeakDirection) {
  const std::string dir = simulate_session("rgbdt_calibrate_verdict_one_view", 1, "--holes 4");
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --camera rgb --seeds none");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_NE(r.output.find("verdict: WARN"), std::string::npos) << r.output;
  const std::string report = read_text(out + "/report.md");
  EXPECT_NE(report.find("WARN: one view: the "), std::string::npos) << report;
  EXPECT_NE(report.find("is weakly constrained"), std::string::npos) << report;
}

// A hopeless session: every view's image belongs to another placement of the board. The
// camera FAILs: exit 2, only the .rejected.yaml (and a stale extrinsics_rgb.yaml of an
// earlier run is gone), the overlays carry the banner, report.md says why.
TEST(RgbdtCalibrate, HopelessSessionFailsAndWritesOnlyTheRejectedEstimate) {
  const std::string dir = simulate_session("rgbdt_calibrate_verdict_hopeless", 4);
  rgbdt::core::CalibrationSession s = rgbdt::core::read_calibration_session(dir);
  const auto original = s.views;
  for (size_t k = 0; k < s.views.size(); ++k) {
    s.views[k].images = original[(k + 2) % s.views.size()].images;
    s.views[k].image_seeds.clear();
  }
  rgbdt::core::write_calibration_session(dir + "/session.yaml", s);
  const std::string out = dir + "/out";
  fs::create_directories(out);
  { std::ofstream(out + "/extrinsics_rgb.yaml") << "stale\n"; }
  // Overlays of views this run does not have, as JPEG and as the PNG of older versions.
  { std::ofstream(out + "/overlay_rgb_099.jpg") << "stale\n"; }
  { std::ofstream(out + "/overlay_rgb_098.png") << "stale\n"; }
  const AppRun r = run_app(dir + " --out " + out + " --camera rgb --seeds none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(out + "/overlay_rgb_099.jpg")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/overlay_rgb_098.png")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/overlay_rgb_000.jpg")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.rejected.yaml")) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_thermal_rgb.yaml")) << r.output;
  EXPECT_NE(r.output.find("verdict: FAIL"), std::string::npos) << r.output;
  const std::string report = read_text(out + "/report.md");
  EXPECT_NE(report.find("**Verdict: FAIL**"), std::string::npos) << report;
}

TEST(RgbdtCalibrate, TranslationBeyondMaxTranslationFailsNamingTheValue) {
  const std::string dir = simulate_session("rgbdt_calibrate_verdict_max_t");
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --camera rgb --seeds none --max-translation 0.01");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("exceeds the maximum of 0.010 m (--max-translation)"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out + "/extrinsics_rgb.yaml")) << r.output;
  EXPECT_TRUE(fs::exists(out + "/extrinsics_rgb.rejected.yaml")) << r.output;
}

// --lidar-only needs no camera: with every image and camera_info gone it writes one CSV row
// per hole of every view (the simulated board's layout times the views).
TEST(RgbdtCalibrate, LidarOnlyWritesEveryHoleWithoutCameras) {
  const std::string dir = simulate_session("rgbdt_calibrate_lidar_only");
  const rgbdt::core::CalibrationSession s = rgbdt::core::read_calibration_session(dir);
  fs::remove_all(dir + "/rgb");
  fs::remove_all(dir + "/thermal");
  for (const auto& [name, camera] : s.cameras) fs::remove(camera.intrinsics);
  const std::string out = dir + "/out";
  const AppRun r = run_app(dir + " --out " + out + " --lidar-only");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::ifstream csv(out + "/detections_lidar.csv");
  ASSERT_TRUE(csv.good()) << r.output;
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line.rfind("view,hole,lidar_x_m,lidar_y_m,lidar_z_m,lidar_radius_m,radius_measured,", 0), 0u) << line;
  size_t rows = 0;
  while (std::getline(csv, line)) rows += line.empty() ? 0 : 1;
  const size_t holes = std::max<size_t>(1, s.target.holes_m.size());
  EXPECT_EQ(rows, s.views.size() * holes) << r.output;
  EXPECT_TRUE(fs::exists(out + "/report.md")) << r.output;
}

}  // namespace

