// End to end through each bag format, written by real ROS tooling: a simulated calibration
// session and a simulated mapping session, each written to a ROS 1 bag by the ROS 1 Python
// libraries (tests/fixtures/write_ros1_calibration_bag.py, write_ros1_bag.py), to a ROS 2 MCAP
// and to a ROS 2 sqlite3 bag folder by @foxglove/rosmsg2-serialization with @mcap/core or
// sql.js (tests/fixtures/mcap/write_mcap.mjs), imported with rgbdt_import and calibrated or
// mapped, score against the ground truth as the original session does.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <regex>
#include <sstream>
#include <tuple>

#include "import_test_util.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::import {
namespace {

namespace fs = std::filesystem;

using test_util::CommandRun;
using test_util::read_text;
using test_util::run_command;

enum class BagFormat { kRos1, kMcap, kDb3 };

std::string format_name(BagFormat format) {
  switch (format) {
    case BagFormat::kRos1:
      return "ros1";
    case BagFormat::kMcap:
      return "mcap";
    case BagFormat::kDb3:
      return "db3";
  }
  return "?";
}

// gtest prints the parameter in test names and failures: the name, not its bytes.
void PrintTo(BagFormat format, std::ostream* os) { *os << format_name(format); }

class ImportEndToEnd : public testing::TestWithParam<BagFormat> {
 protected:
  // Why the fixture writer of the test's format cannot run here ("" when it can): the ROS 2 ones
  // need node and the npm packages of tests/fixtures/mcap. The ROS 1 writer needs Debian's
  // python3-rosbag, which the build's ROS 1 storage (this test's condition) comes with.
  std::string writer_missing() const {
    switch (GetParam()) {
      case BagFormat::kRos1:
        return "";
      case BagFormat::kMcap:
        return test_util::node_fixture_missing({"@mcap/core", "@foxglove/rosmsg2-serialization"});
      case BagFormat::kDb3:
        return test_util::node_fixture_missing({"@foxglove/rosmsg2-serialization", "sql.js"});
    }
    return "unknown format";
  }

  // Writes the session `sim` of `kind` (calibration or mapping) as a bag in the test's format
  // at `dir`/`name` (a file; for db3 a rosbag2 folder, which rgbdt_import takes as the bag) and
  // returns that path.
  fs::path write_bag(const fs::path& sim, const std::string& kind, const fs::path& dir,
                     const std::string& name) const {
    const BagFormat format = GetParam();
    fs::path bag;
    std::string command;
    if (format == BagFormat::kRos1) {
      bag = dir / (name + ".bag");
      command = test_util::ros1_fixture(kind == "calibration" ? "write_ros1_calibration_bag.py"
                                                              : "write_ros1_bag.py") +
                " " + sim.string() + " " + bag.string();
    } else {
      bag = format == BagFormat::kMcap ? dir / (name + ".mcap") : dir / name;
      command = test_util::find_node() + " " +
                (test_util::node_fixture_dir() / "write_mcap.mjs").string() + " --kind " + kind +
                " --format " + format_name(format) + " " + sim.string() + " " + bag.string();
    }
    const CommandRun run = run_command(command, dir / "fixture.log");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return bag;
  }
};

// The result from the bag agrees with the original's when the two errors against the truth
// differ by at most 10 % of the original's, or by at most `floor`: both errors come from the
// same noisy views, and near zero a ratio says nothing (0.002 deg against 0.001 deg is a
// ratio of 2 and no difference a user could see).
void expect_same_error(double from_bag, double original, double floor, const std::string& what) {
  EXPECT_LE(std::abs(from_bag - original), std::max(0.1 * original, floor))
      << what << ": " << from_bag << " from the bag, " << original << " from the original session";
  std::printf("%s: %.6g from the bag, %.6g from the original session (ratio %.4f)\n", what.c_str(),
              from_bag, original, original > 0.0 ? from_bag / original : 1.0);
}

// Each camera's rotation and translation errors against the truth of `truth_calib`, of the
// calibration in `from_bag` against the one in `original` (expect_same_error; floors 0.01 deg
// and 1 mm).
void expect_same_calibration_errors(const fs::path& truth_calib, const fs::path& from_bag,
                                    const fs::path& original) {
  for (const std::string camera : {"rgb", "thermal"}) {
    const std::string file = "extrinsics_" + camera + ".yaml";
    const Eigen::Isometry3d truth = core::read_extrinsics((truth_calib / file).string()).T_parent_child;
    const auto errors = [&](const fs::path& out) {
      const Eigen::Isometry3d T = core::read_extrinsics((out / file).string()).T_parent_child;
      return std::pair{core::rotation_error_rad(T, truth) * 180.0 / M_PI,
                       core::translation_error_m(T, truth)};
    };
    const auto [rotation_original, translation_original] = errors(original);
    const auto [rotation_bag, translation_bag] = errors(from_bag);
    expect_same_error(rotation_bag, rotation_original, 0.01, camera + " rotation error [deg]");
    expect_same_error(translation_bag, translation_original, 0.001,
                      camera + " translation error [m]");
  }
}

// A calibration session of 4 views, as a bag of still intervals and moving gaps,
// imported (the intervals become the views; the board and the camera_info YAML are given, as
// a user gives them) and calibrated: each camera's rotation and translation errors against
// the truth within 10 % (floors 0.01 deg and 1 mm) of rgbdt_calibrate's on the original
// session. Both runs use no seeds: an imported session has none.
TEST_P(ImportEndToEnd, CalibrationThroughABagScoresAsTheOriginalSession) {
  RGBDT_SKIP_WITHOUT_NODE_FIXTURE(writer_missing());
  const fs::path dir = test::temp_dir("work");
  const fs::path sim = dir / "sim", imported = dir / "imported";
  CommandRun run = run_command(
      test::built_program("rgbdt_sim") + " calibration --views 4 --seed 1 --out " + sim.string(),
      dir / "sim.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const fs::path bag = write_bag(sim, "calibration", dir, "calib");
  if (HasFailure()) return;
  const core::CalibrationSession original = core::read_calibration_session(sim.string());
  // The target entry as session.yaml writes it (flow style, one line).
  const std::string yaml = read_text(sim / "session.yaml");
  const std::string target = yaml.substr(8, yaml.find('\n') - 8);
  ASSERT_EQ(yaml.rfind("target: {", 0), 0u) << yaml;
  run = run_command(test::built_program("rgbdt_import") + " " + bag.string() + " --out " +
                        imported.string() +
                        " --kind calibration --lidar /lidar/points --camera rgb=/rgb/image_raw"
                        " --camera thermal=/thermal/image_raw --intrinsics rgb=" +
                        original.cameras.at("rgb").intrinsics + " --intrinsics thermal=" +
                        original.cameras.at("thermal").intrinsics + " --target '" + target + "'",
                    dir / "import.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const core::CalibrationSession from_bag = core::read_calibration_session(imported.string());
  ASSERT_EQ(from_bag.views.size(), original.views.size()) << run.output;

  for (const auto& [session, out] :
       {std::pair{sim, dir / "calib_original"}, std::pair{imported, dir / "calib_bag"}}) {
    run = run_command(test::built_program("rgbdt_calibrate") + " " + session.string() + " --out " +
                          out.string() + " --seeds none",
                      fs::path(out.string() + ".log"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }
  expect_same_calibration_errors(sim / "true_calib", dir / "calib_bag", dir / "calib_original");
}

// A number of summary.json: `"key": 1.5`, or inside `"outer": {... "key": 1.5`.
double json_number(const std::string& json, const std::string& key, const std::string& outer = "") {
  const size_t from = outer.empty() ? 0 : json.find("\"" + outer + "\"");
  std::smatch m;
  const std::string rest = from == std::string::npos ? std::string() : json.substr(from);
  if (!std::regex_search(rest, m, std::regex("\"" + key + "\": ([-+0-9.eE]+)"))) {
    ADD_FAILURE() << "no number " << key << " in summary.json:\n" << json;
    return NAN;
  }
  return std::stod(m[1]);
}

// The trajectory RMSE and thermal error (mean, p95) of the map of summary.json `from_bag`
// against those of `original` (expect_same_error; floors 1 mm and 0.01 K).
void expect_same_map_errors(const std::string& from_bag, const std::string& original) {
  expect_same_error(json_number(from_bag, "trajectory_rmse_m"),
                    json_number(original, "trajectory_rmse_m"), 0.001, "trajectory RMSE [m]");
  expect_same_error(json_number(from_bag, "mean", "thermal_error_k"),
                    json_number(original, "mean", "thermal_error_k"), 0.01, "thermal error, mean [K]");
  expect_same_error(json_number(from_bag, "p95", "thermal_error_k"),
                    json_number(original, "p95", "thermal_error_k"), 0.01, "thermal error, p95 [K]");
}

// The session's radiometry of `camera` as rgbdt_import's --radiometry value, NAME={type: ..}.
std::string radiometry_option(const core::MappingSession& session, const std::string& camera) {
  const core::RadiometrySpec& spec = *session.cameras.at(camera).radiometry;
  std::ostringstream os;
  os << std::setprecision(17) << camera << "={type: " << spec.type;
  for (const auto& [key, value] : spec.parameters) os << ", " << key << ": " << value;
  os << "}";
  return os.str();
}

// A 3 s mapping session through a bag, imported (the thermal camera's radiometry, which a bag does
// not carry, given with --radiometry) and mapped with the true calibration: trajectory RMSE and
// thermal error within 10 % (floors 1 mm and 0.01 K) of rgbdt_mapper's on the original session's
// clouds. The ground truth is not in a bag: it is copied into the imported session. The ROS 2
// writer sends rgb as a CompressedImage (the PNG's bytes), the ROS 1 one as a raw Image.
TEST_P(ImportEndToEnd, MappingThroughABagScoresAsTheOriginalSession) {
  RGBDT_SKIP_WITHOUT_NODE_FIXTURE(writer_missing());
  const fs::path dir = test::temp_dir("work");
  const fs::path sim = dir / "sim", imported = dir / "imported";
  CommandRun run = run_command(test::built_program("rgbdt_sim") + " mapping --out " + sim.string() +
                                   " --duration 3 --rgb-fps 2 --thermal-fps 4 --supersampling 1 -q",
                               dir / "sim.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const fs::path bag = write_bag(sim, "mapping", dir, "map");
  if (HasFailure()) return;
  const std::string rgb_topic =
      GetParam() == BagFormat::kRos1 ? "/rgb/image_raw" : "/rgb/image_raw/compressed";
  const core::MappingSession original = core::read_mapping_session(sim.string());
  run = run_command(test::built_program("rgbdt_import") + " " + bag.string() + " --out " +
                        imported.string() + " --kind mapping --lidar /lidar/points --camera rgb=" +
                        rgb_topic + " --camera thermal=/thermal/image_raw --radiometry '" +
                        radiometry_option(original, "thermal") + "'",
                    dir / "import.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const core::MappingSession from_bag = core::read_mapping_session(imported.string());
  ASSERT_TRUE(from_bag.cameras.at("thermal").radiometry.has_value());
  EXPECT_EQ(from_bag.cameras.at("thermal").radiometry->type,
            original.cameras.at("thermal").radiometry->type);
  EXPECT_EQ(from_bag.cameras.at("thermal").radiometry->parameters,
            original.cameras.at("thermal").radiometry->parameters);
  EXPECT_FALSE(from_bag.cameras.at("rgb").radiometry.has_value());
  fs::copy_file(sim / "ground_truth.yaml", imported / "ground_truth.yaml");
  fs::copy(sim / "ground_truth", imported / "ground_truth", fs::copy_options::recursive);

  std::string summaries[2];
  int k = 0;
  for (const auto& [session, out] :
       {std::pair{sim, dir / "map_original"}, std::pair{imported, dir / "map_bag"}}) {
    // The original through its PCD index, as the imported one (it has no rawlog).
    run = run_command(test::built_program("rgbdt_mapper") + " " + session.string() + " --calib " +
                          (sim / "true_calib").string() + " --out " + out.string() +
                          " --lidar clouds",
                      fs::path(out.string() + ".log"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    summaries[k++] = read_text(out / "summary.json");
  }
  expect_same_map_errors(summaries[1], summaries[0]);
}

// README's route from bags to a map in three commands: one rgbdt_import of the board's bag and
// the drive's bag (ROS 1, by the ROS 1 Python libraries; the drive with an IMU) with the same
// topics, rgbdt_calibrate of OUT/calibration and rgbdt_mapper of OUT/mapping with that
// calibration. The calibration scores as rgbdt_calibrate's on the original session, and the map
// made with it as the original mapping session's made with the original's calibration (10 %,
// floors as above): the route loses nothing against the sessions it came from.
TEST(ImportReadmeRoute, TwoBagsToAMapInThreeCommands) {
  const fs::path dir = test::temp_dir("work");
  const fs::path sim_cal = dir / "sim_cal", sim_map = dir / "sim_map", rig = dir / "rig";
  CommandRun run = run_command(test::built_program("rgbdt_sim") + " calibration --views 4 --seed 1 --out " +
                                   sim_cal.string(),
                               dir / "sim_cal.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  run = run_command(test::built_program("rgbdt_sim") + " mapping --out " + sim_map.string() +
                        " --duration 3 --rgb-fps 2 --thermal-fps 4 --supersampling 1 -q"
                        " --imu-rate 200",
                    dir / "sim_map.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const auto& [script, sim, bag] :
       {std::tuple{"write_ros1_calibration_bag.py", sim_cal, dir / "board.bag"},
        std::tuple{"write_ros1_bag.py", sim_map, dir / "drive.bag"}}) {
    run = run_command(test_util::ros1_fixture(script) + " " + sim.string() + " " + bag.string(),
                      fs::path(bag.string() + ".log"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }
  const core::CalibrationSession original_cal = core::read_calibration_session(sim_cal.string());
  const core::MappingSession original_map = core::read_mapping_session(sim_map.string());
  const std::string yaml = read_text(sim_cal / "session.yaml");
  const std::string target = yaml.substr(8, yaml.find('\n') - 8);

  // 1. Both bags into rig/calibration and rig/mapping.
  run = run_command(test::built_program("rgbdt_import") + " " + (dir / "board.bag").string() + " " +
                        (dir / "drive.bag").string() + " --out " + rig.string() +
                        " --lidar /lidar/points --camera rgb=/rgb/image_raw"
                        " --camera thermal=/thermal/image_raw --imu /imu/data --intrinsics rgb=" +
                        original_cal.cameras.at("rgb").intrinsics + " --intrinsics thermal=" +
                        original_cal.cameras.at("thermal").intrinsics + " --radiometry '" +
                        radiometry_option(original_map, "thermal") + "' --target '" + target + "'",
                    dir / "import.log");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(core::read_calibration_session((rig / "calibration").string()).views.size(),
            original_cal.views.size());
  // The ground truth is not in a bag; with it summary.json scores the map.
  fs::copy_file(sim_map / "ground_truth.yaml", rig / "mapping" / "ground_truth.yaml");
  fs::copy(sim_map / "ground_truth", rig / "mapping" / "ground_truth", fs::copy_options::recursive);

  // 2. and 3., and the same on the original sessions.
  for (const auto& [session, calib, map] :
       {std::tuple{rig / "calibration", rig / "calib", rig / "mapping"},
        std::tuple{sim_cal, dir / "calib_original", sim_map}}) {
    const fs::path out = fs::path(calib.string() + "_map");
    run = run_command(test::built_program("rgbdt_calibrate") + " " + session.string() + " --out " +
                          calib.string() + (session == sim_cal ? " --seeds none" : ""),
                      fs::path(calib.string() + ".log"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    run = run_command(test::built_program("rgbdt_mapper") + " " + map.string() + " --calib " +
                          calib.string() + " --out " + out.string() + " --lidar clouds",
                      fs::path(out.string() + ".log"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }
  expect_same_calibration_errors(sim_cal / "true_calib", rig / "calib", dir / "calib_original");
  const std::string from_bags = read_text(rig / "calib_map" / "summary.json");
  const std::string original = read_text(dir / "calib_original_map" / "summary.json");
  // Both maps took each tilt's rotation from the IMU (the sim's, and its copy through the bag).
  EXPECT_NE(from_bags.find("\"imu\": \"" + (rig / "mapping" / "imu.csv").string() + "\""),
            std::string::npos)
      << from_bags;
  EXPECT_NE(original.find("\"imu\": \"" + (sim_map / "imu.csv").string() + "\""), std::string::npos)
      << original;
  expect_same_map_errors(from_bags, original);
}

INSTANTIATE_TEST_SUITE_P(Bag, ImportEndToEnd,
                         testing::Values(BagFormat::kRos1, BagFormat::kMcap, BagFormat::kDb3),
                         [](const testing::TestParamInfo<BagFormat>& info) {
                           return format_name(info.param);
                         });

}  // namespace
}  // namespace rgbdt::import
