// rgbdt_import: a ROS bag (ROS 2 .mcap or .db3, ROS 1 .bag) into a calibration or mapping
// session folder (design.md's file contracts).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "app_config.hpp"
#include "import.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/thermal_camera/radiometry.hpp"

namespace core = rgbdt::core;
namespace fs = std::filesystem;
namespace imp = rgbdt::import;

namespace {

// "NAME=VALUE" pairs of a repeatable option; throws CLI::ValidationError naming the option.
std::map<std::string, std::string> name_value_pairs(const std::vector<std::string>& items,
                                                    const std::string& option) {
  std::map<std::string, std::string> out;
  for (const std::string& item : items) {
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size()) {
      throw CLI::ValidationError(option, "'" + item + "' is not NAME=VALUE");
    }
    if (!out.emplace(item.substr(0, eq), item.substr(eq + 1)).second) {
      throw CLI::ValidationError(option, "camera " + item.substr(0, eq) + " is given twice");
    }
  }
  return out;
}

constexpr char kDescription[] =
    "rgbdt_import: a ROS bag into an rgbdt session folder (session.yaml, PCD clouds, PNG "
    "frames,\n"
    "camera_info YAML), ready for rgbdt_calibrate or rgbdt_mapper. Given two bags, the board's\n"
    "and the drive's, it writes OUT/calibration and OUT/mapping with the same topics.\n"
    "Bags: ROS 2 MCAP (.mcap), ROS 2 sqlite3 (.db3, a file or a rosbag2 folder), ROS 1 (.bag).\n"
    "Messages: sensor_msgs PointCloud2 (any field layout; per-point times of Velodyne, Ouster,\n"
    "Livox, Hesai), Image (mono8, mono16, 8UC1, 16UC1, rgb8, bgr8, rgba8, bgra8, bayer_*8),\n"
    "CompressedImage (jpeg, png), CameraInfo (plumb_bob, equidistant), Imu.\n"
    "\n"
    "--kind mapping writes clouds/NNNNNN.pcd (x y z, and intensity, ring, t [s from the\n"
    "cloud's earliest point] when the cloud has them; non-finite points and points at the\n"
    "origin (the missing-return marker of Hesai and Ouster drivers) dropped) with\n"
    "clouds/index.csv (time_s = the earliest point's time), <camera>/NNNNNN.png with\n"
    "<camera>/index.csv (time_s = header stamp), <camera>.yaml, session.yaml (with each\n"
    "--radiometry: a bag does not carry a thermal camera's counts -> kelvin), and with --imu\n"
    "imu.csv (time_s,wx,wy,wz,ax,ay,az in the IMU's axes), named by session.yaml's imu entry:\n"
    "rgbdt_mapper takes each tilt's rotation from its gyro. When the IMU's axes are not the\n"
    "LIDAR's, give them as imu: {samples: imu.csv, rotation_lidar_imu: [qx, qy, qz, qw]}.\n"
    "--kind calibration finds the intervals where the board is held still: the first camera's\n"
    "(or --still-camera's) consecutive frames differ by less than --still-threshold; runs of at\n"
    "least --min-still-frames frames are kept. Each kept interval becomes a view: every LIDAR\n"
    "cloud inside it accumulated into clouds/NNN.pcd (non-repetitive LIDARs need it) and each\n"
    "camera's frame nearest its middle as <camera>/NNN.png. One line per interval says whether\n"
    "it was kept and why not. Without --camera, the imported time range is one view (for\n"
    "rgbdt_calibrate --lidar-only).\n"
    "Both kinds write frames.yaml: the LIDAR's and each camera's header.frame_id, which\n"
    "rgbdt_calibrate names its ROS outputs' frames after (--frames overrides it).\n"
    "Times are header stamps (the log time when a stamp is 0). The session is written to a\n"
    "hidden sibling folder and renamed to --out at the end: a failed or interrupted import\n"
    "leaves no session behind. Progress goes to stderr at most once a second.\n"
    "\n"
    "Examples:\n"
    "  rgbdt_import board.bag drive.bag --out rig --lidar /points --camera rgb=/cam/image_raw \\\n"
    "      --target '{type: circle_hole, radius: 0.30}'   # rig/calibration and rig/mapping\n"
    "  rgbdt_import run.mcap --out street --kind mapping --lidar /velodyne_points \\\n"
    "      --camera rgb=/camera/image_raw --camera thermal=/flir/image_raw/compressed \\\n"
    "      --imu /imu/data --start 10 --end 70\n"
    "  rgbdt_import board.bag --out calib --kind calibration --lidar /lidar_points \\\n"
    "      --camera rgb=/camera/image_raw --intrinsics rgb=rgb.yaml \\\n"
    "      --target '{type: circle_hole, radius: 0.12, holes: [[-0.25, 0.2], [0.25, 0.2], "
    "[-0.25, -0.2], [0.25, -0.2]]}'\n"
    "\n"
    "Exit codes: 0 session(s) written; 1 bad input (a topic not in the bag, a type or encoding\n"
    "that cannot be read, a damaged message: named with the topic and the bag); 130\n"
    "interrupted.";

// The command line: ImportOptions and what becomes of them after parsing.
struct Arguments {
  imp::ImportOptions options;
  std::vector<std::string> bags;
  std::string out, kind;
  std::vector<std::string> cameras, camera_infos, intrinsics, radiometry;
  double start_s = 0, end_s = 0;
  CLI::Option* start = nullptr;  // given when *start
  CLI::Option* end = nullptr;
  bool verbose = false;
};

void add_options(CLI::App& app, Arguments& args) {
  imp::ImportOptions& options = args.options;
  app.add_option("BAG", args.bags,
                 "the bag: a .mcap, .db3 or .bag file, or a rosbag2 folder. Two bags: the board's "
                 "(a calibration session, OUT/calibration) and the drive's (a mapping session, "
                 "OUT/mapping), read with the same topics")
      ->required()
      ->expected(1, 2);
  app.add_option("--out", args.out,
                 "the session folder to write (must not exist, or be empty); with two bags the "
                 "folder of both sessions")
      ->required();
  app.add_option("--kind", args.kind,
                 "calibration (still intervals become views) or mapping (every message); "
                 "required with one bag, not given with two")
      ->check(CLI::IsMember({"calibration", "mapping"}));
  app.add_option("--lidar", options.lidar_topic, "the LIDAR's sensor_msgs/PointCloud2 topic")
      ->required();
  app.add_option("--camera", args.cameras,
                 "NAME=TOPIC: a camera's Image or CompressedImage topic (repeatable); NAME is the "
                 "session's camera name, e.g. rgb or thermal");
  app.add_option(
      "--camera-info", args.camera_infos,
      "NAME=TOPIC: the camera's CameraInfo topic (repeatable); default: the image topic's "
      "sibling camera_info (/cam/image_raw[/compressed] -> /cam/camera_info). The first "
      "message becomes <NAME>.yaml");
  app.add_option(
      "--intrinsics", args.intrinsics,
      "NAME=FILE: a camera_info YAML to copy as <NAME>.yaml instead of reading CameraInfo "
      "(repeatable)");
  app.add_option("--radiometry", args.radiometry,
                 "NAME=SPEC: a thermal camera's counts -> kelvin as session.yaml's radiometry entry "
                 "(repeatable), e.g. \"thermal={type: linear, kelvin_per_count: 0.04, offset_k: "
                 "0}\" or {type: planck, R: .., B: .., F: .., O: ..}");
  app.add_option("--imu", options.imu_topic,
                 "a sensor_msgs/Imu topic, written to imu.csv and named by session.yaml "
                 "(mapping; rgbdt_mapper uses its gyro)");
  args.start = app.add_option("--start", args.start_s,
                              "import from this many seconds after the bag's first message "
                              "(one bag only)");
  args.end = app.add_option("--end", args.end_s,
                            "import up to this many seconds after the bag's first message "
                            "(one bag only)");
  app.add_option("--target", options.target_yaml,
                 "calibration: the board as session.yaml's target entry, e.g. '{type: circle_hole, "
                 "radius: 0.30}' or with board_size: [w, h] and holes: [[x, y], ...] [m] (required "
                 "for --kind calibration)");
  app.add_option("--still-threshold", options.still_threshold,
                 "calibration: largest mean absolute grey difference between consecutive frames "
                 "(downscaled to 160 px wide; 8-bit levels, 16-bit frames scaled by the first "
                 "frame's range) that still counts as still; raise it for noisy cameras")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--min-still-frames", options.min_still_frames,
                 "calibration: still runs of fewer frames are dropped")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option(
      "--still-camera", options.still_camera,
      "calibration: the camera whose frames decide stillness (default: the first --camera)");
  app.add_option("--max-view-points", options.max_view_points,
                 "calibration: the most points one view may accumulate (a bound on memory)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("-v,--verbose", args.verbose, "print library log messages (debug level)");
}

// The radiometry entry SPEC of camera `name`, read as session.yaml reads it and checked as the
// mapper checks it; throws CLI::ValidationError naming --radiometry, the camera and the fault.
core::RadiometrySpec parse_radiometry(const std::string& name, const std::string& spec) {
  try {
    const core::MappingSession session = core::parse_mapping_session(
        "lidar: {clouds: c.csv}\ncameras: {" + name + ": {intrinsics: c.yaml, frames: c.csv, " +
            "radiometry: " + spec + "}}\n",
        "option");
    core::RadiometrySpec radiometry = *session.cameras.at(name).radiometry;
    rgbdt::thermal_camera::Radiometry check(radiometry);
    radiometry.source.clear();  // the session written will be its source
    return radiometry;
  } catch (const std::exception& e) {
    // The fault without the stand-in session around it: "radiometry (type linear): key ...".
    const std::string what = e.what();
    const std::size_t at = what.find("radiometry");
    throw CLI::ValidationError(
        "--radiometry", "camera " + name + ": " +
                            (at != std::string::npos
                                 ? what.substr(at)
                                 : "'" + spec + "' is not a YAML map such as {type: linear, "
                                                "kelvin_per_count: 0.04, offset_k: 0}"));
  }
}

// The cameras of --camera, in order, with their --camera-info or --intrinsics; throws
// CLI::ValidationError naming the option of a pair that names no camera or a camera given both.
std::vector<imp::CameraSource> camera_sources(const Arguments& args) {
  const auto camera_map = name_value_pairs(args.cameras, "--camera");
  const auto info_map = name_value_pairs(args.camera_infos, "--camera-info");
  const auto intrinsics_map = name_value_pairs(args.intrinsics, "--intrinsics");
  const auto radiometry_map = name_value_pairs(args.radiometry, "--radiometry");
  std::vector<imp::CameraSource> sources;
  for (const std::string& item : args.cameras) {
    imp::CameraSource source;
    source.name = item.substr(0, item.find('='));
    source.topic = camera_map.at(source.name);
    if (info_map.count(source.name)) source.info_topic = info_map.at(source.name);
    if (intrinsics_map.count(source.name)) source.intrinsics = intrinsics_map.at(source.name);
    if (radiometry_map.count(source.name))
      source.radiometry = parse_radiometry(source.name, radiometry_map.at(source.name));
    if (!source.info_topic.empty() && !source.intrinsics.empty()) {
      throw CLI::ValidationError(
          "--intrinsics", "camera " + source.name + " has both --camera-info and --intrinsics");
    }
    sources.push_back(source);
  }
  for (const auto& [map, option] : {std::pair{&info_map, "--camera-info"},
                                    std::pair{&intrinsics_map, "--intrinsics"},
                                    std::pair{&radiometry_map, "--radiometry"}}) {
    for (const auto& [name, value] : *map) {
      if (!camera_map.count(name)) {
        throw CLI::ValidationError(option, "camera " + name + " is not named by --camera");
      }
    }
  }
  return sources;
}

// The rest of ImportOptions from the parsed command line: one bag with --kind, or two bags
// (the board's and the drive's) without it.
void complete_options(Arguments& args) {
  imp::ImportOptions& options = args.options;
  options.bag = args.bags.front();
  options.out = args.out;
  if (args.bags.size() == 2) {
    if (!args.kind.empty()) {
      throw CLI::ValidationError("--kind", "two bags are the calibration and the mapping session "
                                           "in that order: leave out --kind");
    }
    if (*args.start || *args.end) {
      throw CLI::ValidationError(*args.start ? "--start" : "--end",
                                 "a time window applies to one bag: import the two one by one");
    }
    if (options.target_yaml.empty()) {
      throw CLI::ValidationError("--target", "the first bag is the board's: give the board");
    }
  } else if (args.kind.empty()) {
    throw CLI::RequiredError("--kind (calibration or mapping, with one bag)");
  }
  options.kind =
      args.kind == "mapping" ? imp::SessionKind::kMapping : imp::SessionKind::kCalibration;
  if (*args.start) options.start_s = args.start_s;
  if (*args.end) options.end_s = args.end_s;
  for (const imp::CameraSource& source : camera_sources(args)) options.cameras.push_back(source);
}

void print_summary(const imp::ImportOptions& options, const imp::ImportResult& r,
                   const std::string& out, double seconds) {
  std::string frames;
  for (const auto& [name, n] : r.frames)
    frames += ", " + std::to_string(n) + " " + name + " frames";
  if (options.kind == imp::SessionKind::kMapping) {
    std::printf("mapping session: %zu messages read, %zu clouds%s%s -> %s (%.1f s)\n", r.messages,
                r.clouds, frames.c_str(),
                options.imu_topic.empty()
                    ? ""
                    : (", " + std::to_string(r.imu_samples) + " IMU samples").c_str(),
                out.c_str(), seconds);
  } else {
    std::printf(
        "calibration session: %zu messages read, %zu views from %zu clouds -> %s (%.1f s)\n",
        r.messages, r.views, r.clouds, out.c_str(), seconds);
  }
}

// The import and its summary; returns the exit code.
int run(const imp::ImportOptions& options, const std::string& out) {
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const imp::ImportResult r = imp::import_bag(options, stdout);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    print_summary(options, r, out, seconds);
  } catch (const imp::Interrupted&) {
    std::fprintf(stderr, "rgbdt_import: interrupted; no session was written\n");
    return 130;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_import: error: %s\n", e.what());
    return 1;
  }
  return 0;
}

// Two bags: the board's into OUT/calibration, then the drive's into OUT/mapping, with the same
// topics (the IMU only in the mapping). OUT must not exist or be empty; when either import fails
// or is interrupted, neither session is left behind (nor OUT, when this run made it).
int run_pair(const Arguments& args) {
  const fs::path out = fs::absolute(args.out).lexically_normal();
  std::error_code ec;
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec))) {
    std::fprintf(stderr, "rgbdt_import: error: %s: exists and is not an empty folder (choose a new "
                 "--out)\n", out.string().c_str());
    return 1;
  }
  for (const std::string& bag : args.bags) {
    if (!fs::exists(bag, ec)) {  // before the first import, which may take minutes
      std::fprintf(stderr, "rgbdt_import: error: %s: does not exist\n", bag.c_str());
      return 1;
    }
  }
  const bool made_out = !fs::exists(out, ec);
  imp::ImportOptions calibration = args.options;
  calibration.bag = args.bags[0];
  calibration.out = out / "calibration";
  calibration.kind = imp::SessionKind::kCalibration;
  calibration.imu_topic.clear();
  imp::ImportOptions mapping = args.options;
  mapping.bag = args.bags[1];
  mapping.out = out / "mapping";
  mapping.kind = imp::SessionKind::kMapping;
  int code = run(calibration, calibration.out.string());
  if (code == 0) code = run(mapping, mapping.out.string());
  if (code != 0) {
    fs::remove_all(made_out ? out : calibration.out, ec);
    if (code != 130) std::fprintf(stderr, "rgbdt_import: no session was written\n");
  }
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{kDescription};
  rgbdt::apps::add_config_option(app, argc, argv);
  Arguments args;
  add_options(app, args);
  try {
    app.parse(argc, argv);
    complete_options(args);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(args.verbose ? core::LogLevel::kDebug : core::LogLevel::kWarning);
  core::install_interrupt_handler();
  return args.bags.size() == 2 ? run_pair(args) : run(args.options, args.out);
}
