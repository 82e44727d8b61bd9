// rgbdt_calibrate_intrinsics as a user runs it: bounded search, mixed image sizes, verdicts.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace {

namespace fs = std::filesystem;

std::string bin_dir() {
  const char* dir = std::getenv("RGBDT_BIN_DIR");
  return dir ? dir : std::string(RGBDT_BINARY_DIR) + "/bin";
}

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

struct AppRun {
  int exit_code;
  std::string output;
};

AppRun run_app(const std::string& args, const std::string& log) {
  const int status = std::system((bin_dir() + "/rgbdt_calibrate_intrinsics " + args + " > " + log + " 2>&1").c_str());
  return {WEXITSTATUS(status), read_text(log)};
}

fs::path test_dir(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Simulated RGB board images (1288x964, 8x6 inner corners) in dir/rgb.
void simulate_rgb_boards(const fs::path& dir, int views) {
  const std::string cmd = bin_dir() + "/rgbdt_sim checkerboard --camera rgb --views " + std::to_string(views) +
                          " --out " + dir.string() + " > " + dir.string() + "/sim.log 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

// One RGB-sized image without a pattern: "not found" and exit 1 (the search used to run for
// minutes inside findChessboardCorners).
TEST(RgbdtCalibrateIntrinsics, NoPatternInALargeImageEndsWithNotFound) {
  const fs::path dir = test_dir("rgbdt_calibrate_intrinsics_noise");
  fs::create_directories(dir / "images");
  cv::Mat noise(964, 1288, CV_8U);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::imwrite((dir / "images" / "noise.png").string(), noise);
  rusage before{};
  ::getrusage(RUSAGE_CHILDREN, &before);
  const AppRun r = run_app("--images " + (dir / "images").string() + " --cols 8 --rows 6 --square 0.05 --out " +
                               (dir / "cam.yaml").string(),
                           (dir / "run.log").string());
  rusage after{};
  ::getrusage(RUSAGE_CHILDREN, &after);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("noise.png: pattern 8x6 checkerboard not found"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "cam.yaml"));
  // A hang guard, not a speed target: the search ends in about 0.5 s of CPU; an unbounded
  // findChessboardCorners on such an image runs for minutes (333 s measured).
  const auto cpu_s = [](const rusage& u) {
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  };
  EXPECT_LT(cpu_s(after) - cpu_s(before), 60.0) << "CPU seconds for one image without the pattern";
}

// A stray image of another size (sorted first) does not decide the image size: the largest
// group of images with the pattern is used and the stray one is named as skipped.
TEST(RgbdtCalibrateIntrinsics, AStrayImageOfAnotherSizeIsSkippedAndNamed) {
  const fs::path dir = test_dir("rgbdt_calibrate_intrinsics_stray");
  simulate_rgb_boards(dir, 7);
  const cv::Mat first = cv::imread((dir / "rgb" / "000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(first.empty());
  cv::Mat half;
  cv::resize(first, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  cv::imwrite((dir / "rgb" / "aaa_stray.png").string(), half);
  const AppRun r = run_app("--images " + (dir / "rgb").string() + " --cols 8 --rows 6 --square 0.0508 --out " +
                               (dir / "cam.yaml").string() + " --report " + (dir / "report").string(),
                           (dir / "run.log").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "cam.yaml")) << r.output;
  EXPECT_NE(r.output.find("skipped aaa_stray.png: size 644x482 differs from the 1288x964"), std::string::npos)
      << r.output;
  const std::string report = read_text((dir / "report" / "report.md").string());
  EXPECT_NE(report.find("aaa_stray.png: size 644x482"), std::string::npos) << report;
}

// An estimate that fails its checks is reported as failed, exits non-zero and is not
// written; report.md says so.
TEST(RgbdtCalibrateIntrinsics, AnEstimateThatFailsItsChecksIsNotWritten) {
  const fs::path dir = test_dir("rgbdt_calibrate_intrinsics_verdict");
  simulate_rgb_boards(dir, 6);
  const AppRun r = run_app("--images " + (dir / "rgb").string() + " --cols 8 --rows 6 --square 0.0508 --out " +
                               (dir / "cam.yaml").string() + " --report " + (dir / "report").string() +
                               " --max-rms 0.000001",
                           (dir / "run.log").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(dir / "cam.yaml")) << r.output;
  EXPECT_NE(r.output.find("calibration failed its checks: RMS reprojection error"), std::string::npos) << r.output;
  const std::string report = read_text((dir / "report" / "report.md").string());
  EXPECT_NE(report.find("**FAILED: RMS reprojection error"), std::string::npos) << report;
}

}  // namespace
