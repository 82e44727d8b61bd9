// Real data end to end: rgbdt_calibrate on the ART-BP/calib session (3 poses of a 4-hole
// board, 16-ring Hesai, 1920x1080 fisheye; see art_bp_detection_test.cpp and the fixture
// real_data_art_bp_session) with automatic detection everywhere, against the authors'
// LiDAR->camera result (_history/8628e54.../output/multi_calib_result.txt).
//
// Tolerances, from what 3 views of a 16-ring LIDAR and the authors' own spread support:
// - Each LIDAR hole centre is known to about 1 cm vertically and a few mm horizontally (two
//   rings cross each hole; art_bp_detection_test.cpp derives it). 12 holes over a 0.5 x 0.4 m
//   layout at 2.6 m constrain the rotation to about 1 cm / 0.5 m / sqrt(12) = 0.33 deg
//   (1 sigma), and through the 2.6 m lever arm that rotation moves the translation by
//   about 1.5 cm.
// - The authors' result itself moved by 0.2 deg and 6 mm between their two published runs
//   on these scenes (_history/080943f vs 8628e54).
// Combined: 0.6 deg in rotation and 3 cm in translation.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/test/process.hpp"

namespace rgbdt {
namespace {

namespace fs = std::filesystem;

constexpr double kRotationTolDeg = 0.6;
constexpr double kTranslationTolM = 0.03;

std::string read_all(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(ArtBpCalibration, MatchesTheAuthorsResult) {
  // Skipped until the detectors find the target in these views (art_bp_detection_test.cpp);
  // RGBDT_RUN_KNOWN_FAILURES=1 runs it.
  if (const char* v = std::getenv("RGBDT_RUN_KNOWN_FAILURES"); v == nullptr || std::string(v) != "1") {
    GTEST_SKIP() << "known failure: rgbdt_calibrate exits 2, 'camera rgb: not calibrated: the "
                    "target was never found (LIDAR in 3 of 3 views, rgb image in 0)'";
  }
  const fs::path session = ART_BP_SESSION_DIR;
  ASSERT_TRUE(fs::exists(session / "session.yaml"))
      << "missing " << session / "session.yaml" << ": run the fixture (ctest -R real_data_art_bp_session)";
  const fs::path out = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "art_bp_calibration";
  fs::remove_all(out);
  fs::create_directories(out);
  const fs::path log = out.string() + ".log";

  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = test::spawn_with_log(test::built_program("rgbdt_calibrate"),
                                         {session.string(), "--out", out.string(), "--camera", "rgb",
                                          "--seeds", "none"},
                                         log);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string output = read_all(log);
  std::printf("rgbdt_calibrate: %.2f s wall\n%s\n", seconds, output.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << "rgbdt_calibrate failed (status " << status << "):\n" << output << "\nreport.md:\n"
      << read_all(out / "report.md");
  ASSERT_TRUE(fs::exists(out / "extrinsics_rgb.yaml")) << output;

  const core::ExtrinsicsFrames frames{"rgb"};
  const Eigen::Isometry3d ours = core::read_extrinsics((out / "extrinsics_rgb.yaml").string(), frames).T_parent_child;
  const Eigen::Isometry3d theirs =
      core::read_extrinsics((session / "reference" / "extrinsics_rgb.yaml").string(), frames).T_parent_child;
  const double rotation_deg =
      Eigen::AngleAxisd(ours.linear() * theirs.linear().transpose()).angle() * 180.0 / M_PI;
  const Eigen::Vector3d dt = ours.translation() - theirs.translation();
  std::printf("against the authors: rotation %.3f deg, translation %.2f cm (dx %.2f dy %.2f dz %.2f cm)\n",
              rotation_deg, 100.0 * dt.norm(), 100.0 * dt.x(), 100.0 * dt.y(), 100.0 * dt.z());
  EXPECT_LT(rotation_deg, kRotationTolDeg);
  EXPECT_LT(dt.norm(), kTranslationTolM);
}

}  // namespace
}  // namespace rgbdt
