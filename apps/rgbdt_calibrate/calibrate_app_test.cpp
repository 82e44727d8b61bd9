// rgbdt_calibrate as a user runs it: exit codes and messages.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/session.hpp"

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

}  // namespace
