// A simulated mapping session written to a ROS 2 MCAP by the npm registry's real ROS 2 tooling
// (tests/fixtures/mcap/write_mcap.mjs: @mcap/core, @foxglove/rosmsg2-serialization; run with
// Debian's nodejs), imported back with rgbdt_import: the same points, pixels, intrinsics and
// IMU samples. Skipped, naming the reason, where node or the fixture's node_modules
// (scripts/install-deps: npm ci --prefix tests/fixtures/mcap) is missing.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "import_test_util.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::import {
namespace {

namespace fs = std::filesystem;

using test_util::CommandRun;
using test_util::run_command;

// Rows of a CSV with a header line, each split at commas.
std::vector<std::vector<std::string>> read_csv(const fs::path& path, std::string* header) {
  std::ifstream f(path);
  EXPECT_TRUE(f.good()) << "cannot read " << path;
  std::getline(f, *header);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

TEST(ImportMcapFixture, SimMappingSessionRoundTripsThroughAnMcapWrittenByRos2Tooling) {
  RGBDT_SKIP_WITHOUT_NODE_FIXTURE(
      test_util::node_fixture_missing({"@mcap/core", "@foxglove/rosmsg2-serialization"}));
  const fs::path fixture = test_util::node_fixture_dir();
  const std::string node = test_util::find_node();

  const fs::path dir = test::temp_dir("work");
  const fs::path sim = dir / "sim", mcap = dir / "sim.mcap", out = dir / "imported";
  // 1.5 s: two tilts (0.6 s each), 3 rgb and 8 thermal frames; supersampling 1 for speed.
  CommandRun run =
      run_command(test::built_program("rgbdt_sim") + " mapping --out " + sim.string() +
                      " --duration 1.5 --rgb-fps 2 --thermal-fps 5 --supersampling 1 -q",
                  dir / "sim.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  run = run_command(
      node + " " + (fixture / "write_mcap.mjs").string() + " " + sim.string() + " " + mcap.string(),
      dir / "fixture.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  // rgb travels as CompressedImage (the PNG's bytes), thermal as a raw mono16 Image; the
  // CameraInfo topics are the image topics' siblings (the default).
  run = run_command(
      test::built_program("rgbdt_import") + " " + mcap.string() + " --out " + out.string() +
          " --kind mapping --lidar /lidar/points"
          " --camera rgb=/rgb/image_raw/compressed --camera thermal=/thermal/image_raw"
          " --imu /imu/data",
      dir / "import.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;

  test_util::expect_same_mapping_session(sim.string(), out.string());

  // imu.csv, named by session.yaml for rgbdt_mapper: the samples the fixture wrote
  // (OUT.mcap.imu.csv, time in ns), row for row.
  const core::MappingSession session = core::read_mapping_session(out.string());
  ASSERT_TRUE(session.imu.has_value());
  EXPECT_EQ(fs::path(session.imu->samples), fs::absolute(out / "imu.csv"));
  EXPECT_TRUE(session.imu->rotation_lidar_imu.isApprox(Eigen::Quaterniond::Identity()));
  std::string want_header, got_header;
  const auto want = read_csv(mcap.string() + ".imu.csv", &want_header);
  const auto got = read_csv(out / "imu.csv", &got_header);
  EXPECT_EQ(got_header, "time_s,wx,wy,wz,ax,ay,az");
  ASSERT_EQ(want.size(), 20u);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(got[i].size(), 7u) << "imu row " << i;
    ASSERT_EQ(want[i].size(), 7u) << "imu row " << i;
    const double want_time = double(std::stoll(want[i][0])) * 1e-9;
    EXPECT_NEAR(std::stod(got[i][0]), want_time, 1e-9) << "imu row " << i;
    for (int c = 1; c < 7; ++c)  // both sides print round-trip text of the same double
      EXPECT_EQ(std::stod(got[i][c]), std::stod(want[i][c])) << "imu row " << i << " column " << c;
  }
}

}  // namespace
}  // namespace rgbdt::import
