// Intrinsic calibration on the simulated 40-view thermal checkerboard set (paper Sec. 3.1)
// against the simulator's true intrinsics: the issue's accuracy targets.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "rgbdt/calib_targets/intrinsics.hpp"
#include "rgbdt/sim/checkerboard_session.hpp"

namespace ct = rgbdt::calib_targets;
namespace fs = std::filesystem;

namespace {
/// The simulated board's inner-corner checkerboard.
ct::PatternSpec inner_corners(const rgbdt::sim::CheckerboardSessionOptions& opt) {
  ct::PatternSpec pattern;
  pattern.cols = opt.squares_x - 1;
  pattern.rows = opt.squares_y - 1;
  pattern.spacing_m = opt.square_m;
  return pattern;
}
}  // namespace

TEST(ThermalIntrinsicsSim, FortyViewsMeetIssueTargets) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "calib_targets_thermal_intrinsics";
  fs::remove_all(dir);
  rgbdt::sim::CheckerboardSessionOptions opt;
  opt.camera = "thermal";
  opt.views = 40;  // the paper's count (Sec. 3.1) and the issue's test set
  opt.seed = 1;
  const auto truth = rgbdt::sim::write_checkerboard_session(dir.string(), opt);
  ASSERT_EQ(truth.views.size(), 40u);

  ct::PatternSpec pattern;
  pattern.type = ct::PatternType::kCheckerboard;
  pattern.cols = opt.squares_x - 1;  // 8x6 inner corners
  pattern.rows = opt.squares_y - 1;
  pattern.spacing_m = opt.square_m;

  std::vector<ct::PatternDetection> detections;
  std::vector<std::string> names;
  cv::Size size;
  int detected = 0;
  for (std::size_t v = 0; v < truth.views.size(); ++v) {
    char name[32];
    std::snprintf(name, sizeof(name), "%03zu.png", v);
    const fs::path file = dir / "thermal" / name;
    const cv::Mat img = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << file;
    ASSERT_EQ(img.depth(), CV_16U) << file << ": thermal views are 16-bit counts";
    size = img.size();
    detections.push_back(ct::detect_pattern(img, pattern));
    names.push_back(name);
    if (detections.back().ok) ++detected;
  }
  // Issue: automatic detection on the thermal set; allow 2 of 40 views (5 %) to be
  // missed or rejected as unreliable, since the simulator draws poses up to 40 deg tilt
  // and 0.7-1.6 m where a board may be partly blurred; 38 views are still far more than
  // the ~10-20 views a stable pinhole + distortion fit needs.
  EXPECT_GE(detected, 38) << "of 40 views";

  const auto result = ct::calibrate_intrinsics(detections, names, size, pattern);
  ASSERT_TRUE(result.ok) << result.reason;
  const double fx_err = std::abs(result.intrinsics.fx - truth.intrinsics.fx) / truth.intrinsics.fx;
  const double fy_err = std::abs(result.intrinsics.fy - truth.intrinsics.fy) / truth.intrinsics.fy;
  std::cout << "detected " << detected << "/40, RMS " << result.rms_px << " px, fx "
            << result.intrinsics.fx << " (true " << truth.intrinsics.fx << ", " << 100.0 * fx_err
            << " %), fy " << result.intrinsics.fy << " (true " << truth.intrinsics.fy << ", "
            << 100.0 * fy_err << " %), terms " << result.distortion_terms << "\n";
  // Issue targets: RMS <= 0.25 px, the paper's thermal result with RADOCC (Sec. 3.1,
  // 0.24 px), which we must at least match on simulated 640x512 images with NETD noise and
  // blur; fx, fy within 0.3 % of the truth (~1.25 px at fx ~417), small enough that the
  // focal-length error stays below the paper's error model's other terms.
  EXPECT_LE(result.rms_px, 0.25);
  EXPECT_LE(fx_err, 0.003);
  EXPECT_LE(fy_err, 0.003);
  fs::remove_all(dir);
}

// The RGB camera's simulated board images (1288x964) are found, each corner within a pixel
// of the truth: the search runs on a downscaled copy and the corners are refined at full
// resolution.
// Night thermal images of the board (almost no contrast between the squares): no detector
// finds it (all attempts: 10.7 s an image), and the quick checkerboard test rules each out
// before the long attempts, saying so.
TEST(ThermalIntrinsicsSim, NightBoardsWithoutContrastAreRuledOutByTheQuickTest) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "calib_targets_thermal_night";
  fs::remove_all(dir);
  rgbdt::sim::CheckerboardSessionOptions opt;
  opt.camera = "thermal";
  opt.views = 3;
  opt.seed = 4;
  opt.time_of_day = rgbdt::sim::TimeOfDay::kNight;
  const auto truth = rgbdt::sim::write_checkerboard_session(dir.string(), opt);
  ASSERT_EQ(truth.views.size(), 3u);
  const ct::PatternSpec pattern = inner_corners(opt);
  for (std::size_t v = 0; v < truth.views.size(); ++v) {
    char name[48];
    std::snprintf(name, sizeof(name), "thermal/%03zu.png", v);
    const cv::Mat image = cv::imread((dir / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    const ct::PatternDetection d = ct::detect_pattern(image, pattern);
    EXPECT_FALSE(d.ok) << name << ": " << d.method;
    EXPECT_NE(d.reason.find("no image variant looks like a checkerboard"), std::string::npos) << name << ": " << d.reason;
  }
  fs::remove_all(dir);
}

TEST(RgbIntrinsicsSim, SimulatedRgbBoardIsFoundAtFullResolution) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "calib_targets_rgb_board";
  fs::remove_all(dir);
  rgbdt::sim::CheckerboardSessionOptions opt;
  opt.camera = "rgb";
  opt.views = 4;
  opt.seed = 1;
  const auto truth = rgbdt::sim::write_checkerboard_session(dir.string(), opt);
  ASSERT_EQ(truth.views.size(), 4u);
  const ct::PatternSpec pattern = inner_corners(opt);
  for (std::size_t v = 0; v < truth.views.size(); ++v) {
    char name[32];
    std::snprintf(name, sizeof(name), "rgb/%03zu.png", v);
    const cv::Mat image = cv::imread((dir / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    ASSERT_EQ(image.cols, 1288) << name;
    const ct::PatternDetection d = ct::detect_pattern(image, pattern);
    ASSERT_TRUE(d.ok) << name << ": " << d.reason;
    ASSERT_EQ(d.points.size(), truth.views[v].corners_px.size());
    // The detector may number the grid from either end; compare with the nearer order.
    double err_fwd = 0.0, err_rev = 0.0;
    const std::size_t n = d.points.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector2d& t = truth.views[v].corners_px[k];
      err_fwd = std::max(err_fwd, std::hypot(d.points[k].x - t.x(), d.points[k].y - t.y()));
      err_rev = std::max(err_rev, std::hypot(d.points[n - 1 - k].x - t.x(), d.points[n - 1 - k].y - t.y()));
    }
    EXPECT_LT(std::min(err_fwd, err_rev), 1.0) << name << " (" << d.method << ")";
  }
}
