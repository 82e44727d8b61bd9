#pragma once
// What the rgbdt_import tests share: running a command with its output kept, the system
// Python (Debian's ROS 1 modules live in its dist-packages), node and the ROS 2 fixture
// writer's npm packages, and the check that a session imported from a bag equals the
// simulated session the bag was written from.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"

namespace rgbdt::import::test_util {

struct CommandRun {
  int exit_code;
  std::string output;
};

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Runs `command` through the shell with stdout and stderr to `log`.
inline CommandRun run_command(const std::string& command, const std::filesystem::path& log) {
  std::filesystem::create_directories(log.parent_path());
  const int status = std::system((command + " > " + log.string() + " 2>&1").c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text(log)};
}

/// "python3 <source>/tests/fixtures/<script>" with Debian's Python, which has python3-rosbag.
inline std::string ros1_fixture(const std::string& script) {
  const std::string python =
      std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  return python + " " + RGBDT_SOURCE_DIR + "/tests/fixtures/" + script;
}

/// The node program on PATH, or "" when there is none.
inline std::string find_node() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::filesystem::path candidate = std::filesystem::path(dir.empty() ? "." : dir) / "node";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

/// <source>/tests/fixtures/mcap: write_mcap.mjs and its package.json.
inline std::filesystem::path node_fixture_dir() {
  return std::filesystem::path(RGBDT_SOURCE_DIR) / "tests" / "fixtures" / "mcap";
}

/// Why the ROS 2 fixture writer (tests/fixtures/mcap/write_mcap.mjs) cannot run here, or ""
/// when it can: node must be on PATH and `packages` (npm names) in its node_modules. A test
/// skips with this reason (node and npm come from scripts/install-deps, not from the build),
/// except under CI (RGBDT_SKIP_WITHOUT_NODE_FIXTURE).
inline std::string node_fixture_missing(const std::vector<std::string>& packages) {
  if (find_node().empty())
    return "node is not on PATH (Debian package nodejs; scripts/install-deps)";
  const std::filesystem::path modules = node_fixture_dir() / "node_modules";
  for (const std::string& package : packages) {
    if (!std::filesystem::is_directory(modules / package)) {
      return modules.string() + " lacks " + package + ": run npm ci --prefix " +
             node_fixture_dir().string() + " (scripts/install-deps does)";
    }
  }
  return "";
}

/// Skips the test when the ROS 2 fixture writer cannot run (`missing` says why), but fails it
/// when the environment sets CI (as `CI=true bash .ci/run` does): CI installs node and the
/// npm packages first, so a missing one there is a broken install, not a machine without node.
#define RGBDT_SKIP_WITHOUT_NODE_FIXTURE(missing)                                    \
  do {                                                                              \
    if (const std::string why_ = (missing); !why_.empty()) {                        \
      if (std::getenv("CI") != nullptr) FAIL() << why_ << " (CI is set: required)"; \
      GTEST_SKIP() << why_;                                                         \
    }                                                                               \
  } while (false)

/// The mapping session imported into `imported_dir` equals the simulated one in `sim_dir`:
/// every cloud point for point (x y z, intensity and ring exactly: they travel as the same
/// float32 and uint16 values; t, float32 s -> integer ns -> float32 s, within 1 ns plus the
/// float rounding of a value below 1 s), every frame pixel for pixel at its time (stamps go
/// through whole ns), and the cameras' intrinsics.
inline void expect_same_mapping_session(const std::string& sim_dir,
                                        const std::string& imported_dir) {
  const core::MappingSession original = core::read_mapping_session(sim_dir);
  const core::MappingSession imported = core::read_mapping_session(imported_dir);
  const auto clouds_before = core::read_time_index(original.lidar.clouds);
  const auto clouds_after = core::read_time_index(imported.lidar.clouds);
  ASSERT_EQ(clouds_after.size(), clouds_before.size());
  ASSERT_GE(clouds_before.size(), 2u);
  for (std::size_t i = 0; i < clouds_before.size(); ++i) {
    EXPECT_NEAR(clouds_after[i].time_s, clouds_before[i].time_s, 1e-9) << "cloud " << i;
    const cloud::LoadedCloud a = cloud::load_pcd(clouds_before[i].file);
    const cloud::LoadedCloud b = cloud::load_pcd(clouds_after[i].file);
    ASSERT_EQ(b.cloud->size(), a.cloud->size()) << "cloud " << i;
    EXPECT_TRUE(b.has_intensity && b.has_ring && b.has_t);
    for (std::size_t k = 0; k < a.cloud->size(); ++k) {
      const auto& p = a.cloud->points[k];
      const auto& q = b.cloud->points[k];
      ASSERT_EQ(q.x, p.x) << "cloud " << i << " point " << k;
      ASSERT_EQ(q.y, p.y) << "cloud " << i << " point " << k;
      ASSERT_EQ(q.z, p.z) << "cloud " << i << " point " << k;
      ASSERT_EQ(q.intensity, p.intensity) << "cloud " << i << " point " << k;
      ASSERT_EQ(q.ring, p.ring) << "cloud " << i << " point " << k;
      ASSERT_NEAR(q.t, p.t, 1e-7) << "cloud " << i << " point " << k;
    }
  }
  for (const char* name : {"rgb", "thermal"}) {
    const auto frames_before = core::read_time_index(original.cameras.at(name).frames);
    const auto frames_after = core::read_time_index(imported.cameras.at(name).frames);
    ASSERT_EQ(frames_after.size(), frames_before.size()) << name;
    ASSERT_GE(frames_before.size(), 2u) << name;
    for (std::size_t i = 0; i < frames_before.size(); ++i) {
      EXPECT_NEAR(frames_after[i].time_s, frames_before[i].time_s, 1e-9) << name << " " << i;
      const cv::Mat a = cv::imread(frames_before[i].file, cv::IMREAD_UNCHANGED);
      const cv::Mat b = cv::imread(frames_after[i].file, cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(a.empty()) << frames_before[i].file;
      ASSERT_EQ(b.type(), a.type()) << name << " " << i;
      ASSERT_EQ(b.size(), a.size()) << name << " " << i;
      EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << name << " frame " << i << " differs";
    }
    const core::CameraIntrinsics a = core::read_camera_info(original.cameras.at(name).intrinsics);
    const core::CameraIntrinsics b = core::read_camera_info(imported.cameras.at(name).intrinsics);
    EXPECT_EQ(b.width, a.width) << name;
    EXPECT_EQ(b.height, a.height) << name;
    EXPECT_EQ(b.fx, a.fx) << name;
    EXPECT_EQ(b.fy, a.fy) << name;
    EXPECT_EQ(b.cx, a.cx) << name;
    EXPECT_EQ(b.cy, a.cy) << name;
    EXPECT_EQ(b.model, a.model) << name;
    EXPECT_EQ(b.distortion, a.distortion) << name;
  }
}

}  // namespace rgbdt::import::test_util
