// rgbdt_mapper: RGB-Depth-Thermal map of a mapping session (paper Sec. 5).
//
//   rgbdt_mapper SESSION --calib DIR --out OUT [--resolution 0.05] [--lidar auto|rawlog|clouds]
//
// Reads the LIDAR from the session's raw MRPT rawlog through tilt_lidar's Assembler (one
// cloud per tilt) when the session has one and its tilt_rig.yaml, else from the assembled
// PCD index. Registers the tilt clouds into a trajectory (GICP against a local map),
// colours every point from the RGB and thermal frames nearest in time (motion compensated,
// occlusion aware), accumulates a voxel map and writes:
//   OUT/map.ply map.pcd                 coloured points with temperature [K]
//   OUT/map.bt                          OctoMap occupancy (ray-inserted, free space known)
//   OUT/map_rgb.ot map_thermal.ot       ColorOcTree and ThermalOcTree
//   OUT/trajectory.csv                  time_s,x,y,z,qx,qy,qz,qw of T_world_lidar
//   OUT/render_{rgb,thermal}_{top,perspective}.png
//   OUT/summary.json                    counts, coloured fractions, stage times, trajectory error,
//                                       thermal error against ground truth (simulated sessions)
// Colour outputs (map_rgb.ot, render_rgb_*; map_thermal.ot, render_thermal_*) are written
// only when some point took that colour; summary.json names what was not written and why.
//
// Before the long work a preflight checks every file the session names (camera_info,
// extrinsics, frame indexes, every frame's PNG header against its camera_info, the cloud
// files) and lists every problem at once; nothing is written then. Every output is written
// to a temporary sibling and renamed into place; summary.json is written last and marks a
// complete run (a stale one in OUT is removed first). Ctrl-C stops at the next cloud and
// writes nothing half-done (exit 130).
#include <CLI/CLI.hpp>
#include <yaml-cpp/yaml.h>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>

#include "app_config.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/image_header.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/core/yaml_util.hpp"
#include "rgbdt/rgbdt_map/colorize.hpp"
#include "rgbdt/rgbdt_map/export.hpp"
#include "rgbdt/rgbdt_map/imu.hpp"
#include "rgbdt/rgbdt_map/registration.hpp"
#include "rgbdt/rgbdt_map/render.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"
#include "rgbdt/rgbdt_map/voxel_map.hpp"
#include "rgbdt/thermal_camera/radiometry.hpp"
#include "rgbdt/tilt_lidar/assembler.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"

namespace fs = std::filesystem;
using namespace rgbdt;
using namespace rgbdt::rgbdt_map;

namespace {

using Clock = std::chrono::steady_clock;

/// A camera frame colours a cloud only when taken within this time of the cloud's middle
/// (the poses that move points to the frame's time are known only around the tilts) [s].
constexpr double kMaxFrameGapS = 1.0;
double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Camera {
  Camera(std::string camera_name, MappedCamera camera) : name(std::move(camera_name)), mapped(std::move(camera)) {}
  std::string name;
  MappedCamera mapped;
  std::vector<core::TimedFile> frames;
  bool thermal = false;
  // Last image loaded (consecutive clouds often share a frame).
  std::string loaded_path;
  cv::Mat image;
  // Statistics.
  std::size_t colored = 0, occluded = 0, in_view = 0;
  std::size_t clouds_without_frame = 0;  ///< clouds with no frame within kMaxFrameGapS
  double decode_s = 0.0;  ///< time spent reading and decoding its images

  const cv::Mat& load(const std::string& path) {
    if (path != loaded_path) {
      const auto start = std::chrono::steady_clock::now();
      image = cv::imread(path, thermal ? cv::IMREAD_ANYDEPTH : cv::IMREAD_COLOR);
      decode_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (image.empty()) throw core::Error(path, "cannot read image (expected a PNG)");
      loaded_path = path;
    }
    return image;
  }
};

/// Counts -> kelvin of the session's radiometry entry (thermal_camera::Radiometry: linear
/// TLinear or Planck with emissivity and reflected temperature).
thermal_camera::Radiometry thermal_radiometry(const core::CameraEntry& entry, const std::string& session,
                                              const std::string& camera) {
  if (!entry.radiometry) {
    throw core::Error(session, "camera '" + camera + "' has no radiometry (expected radiometry: {type: linear, "
                               "kelvin_per_count: K, offset_k: K} or {type: planck, R, B, F, O, ...})");
  }
  try {
    return thermal_camera::Radiometry(*entry.radiometry);
  } catch (const std::invalid_argument& e) {
    throw core::Error(session, "camera '" + camera + "' radiometry: " + e.what());
  }
}

/// One tilt cloud of the session: read from its PCD when needed, or kept in memory after
/// the rawlog was assembled.
struct TiltSource {
  double time_s = 0.0;  ///< time of the cloud's first point (its t = 0)
  std::string file;     ///< PCD, or empty when `cloud` holds the points
  cloud::Cloud::Ptr cloud;

  cloud::LoadedCloud load() const {
    if (cloud) return cloud::LoadedCloud{cloud, true, true, true};
    return cloud::load_cloud(file);
  }
};

/// Replays the raw stream through tilt_lidar's Assembler. Tilts with fewer scan lines than
/// 80 % of the median (the stream's cut-off ends) are dropped, like the PCD index does.
std::vector<TiltSource> assemble_rawlog(const core::MappingSession& session, std::string* report) {
  const core::TiltRig rig = core::read_tilt_rig(session.lidar.rig);
  tilt_lidar::Assembler assembler(rig);
  std::vector<tilt_lidar::TiltCloud> tilts;
  const tilt_lidar::ReplayResult replay =
      tilt_lidar::replay_rawlog(session.lidar.rawlog, assembler, [&](tilt_lidar::TiltCloud&& tilt) {
        tilt.spherical.clear();
        tilt.spherical.shrink_to_fit();
        tilts.push_back(std::move(tilt));
      });
  if (replay.truncated) core::log_warning(session.lidar.rawlog, ": ", replay.error, " (using what was read)");
  std::vector<int> scans;
  for (const auto& t : tilts) scans.push_back(t.stats.scans);
  int median = 0;
  if (!scans.empty()) {
    std::nth_element(scans.begin(), scans.begin() + scans.size() / 2, scans.end());
    median = scans[scans.size() / 2];
  }
  std::vector<TiltSource> out;
  for (auto& t : tilts) {
    if (!t.cloud || t.cloud->empty() || t.stats.scans < 0.8 * median) continue;
    out.push_back({t.start_time_s, "", t.cloud});
  }
  const tilt_lidar::AssemblerStats& st = assembler.stats();
  std::ostringstream os;
  os << "{\"scans\": " << st.scans << ", \"encoder_samples\": " << st.encoder_samples << ", \"points\": " << st.points
     << ", \"tilts\": " << tilts.size() << ", \"tilts_used\": " << out.size()
     << ", \"dropped_gap\": " << st.dropped_gap << ", \"dropped_no_encoder\": " << st.dropped_no_encoder
     << ", \"truncated\": " << (replay.truncated ? "true" : "false") << "}";
  *report = os.str();
  return out;
}

/// Simulated sessions' true apparent temperature of every LIDAR beam (ground_truth.yaml
/// beam_temperature: a 16-bit image, row = scan, column = beam).
class BeamTemperatureTruth {
 public:
  static std::optional<BeamTemperatureTruth> load(const std::string& session_dir) {
    const fs::path yaml = fs::path(session_dir) / "ground_truth.yaml";
    if (!fs::exists(yaml)) return std::nullopt;
    const core::YamlField root(core::load_yaml_file(yaml.string()), yaml.string());
    const std::optional<core::YamlField> node = root.find("beam_temperature");
    if (!node) return std::nullopt;
    BeamTemperatureTruth truth;
    fs::path image = node->at("image", "a 16-bit PNG of beam temperatures").as_string("a file path");
    if (image.is_relative()) image = fs::path(session_dir) / image;
    (void)core::read_image_header(image.string());  // refuses a size too large to decode
    truth.units_ = cv::imread(image.string(), cv::IMREAD_UNCHANGED);
    if (truth.units_.type() != CV_16UC1) {
      throw core::Error(image.string(), "expected a 16-bit single-channel PNG of beam temperatures");
    }
    truth.kelvin_per_unit_ =
        node->at("kelvin_per_unit", "kelvin per image unit").as_double_in(1e-9, 1.0, "kelvin per image unit in (0, 1]");
    truth.first_scan_s_ = node->at("first_scan_time_s", "a time [s]").as_double();
    truth.scan_period_s_ = node->at("scan_period_s", "a scan period [s]").as_double_in(1e-4, 10.0, "a scan period in [1e-4, 10] s");
    truth.beam_period_s_ =
        truth.scan_period_s_ /
        static_cast<double>(node->at("steps_per_revolution", "steps per revolution").as_integer(1, 1 << 20, "steps per revolution in 1..2^20"));
    return truth;
  }
  /// True temperature [K] of the beam measured at time_s, NaN if unknown.
  double kelvin_at(double time_s) const {
    const double since = time_s - first_scan_s_;
    // A UTM-30LX scan's 1081 beams take 3/4 of the scan period, so a beam time sits at
    // least 1/4 period before the next scan: the 0.1 margin absorbs time rounding.
    const long scan = static_cast<long>(std::floor(since / scan_period_s_ + 0.1));
    const long beam = std::lround((since - scan * scan_period_s_) / beam_period_s_);
    if (scan < 0 || scan >= units_.rows || beam < 0 || beam >= units_.cols) return NAN;
    const std::uint16_t v = units_.at<std::uint16_t>(static_cast<int>(scan), static_cast<int>(beam));
    return v == 0 ? NAN : v * kelvin_per_unit_;
  }

 private:
  cv::Mat units_;
  double kelvin_per_unit_ = 0.01, first_scan_s_ = 0.0, scan_period_s_ = 0.025, beam_period_s_ = 0.025 / 1440;
};

/// Absolute errors of coloured points' temperatures against the truth.
struct ThermalErrors {
  static std::string number(double v) {
    if (!std::isfinite(v)) return "null";
    std::ostringstream os;
    os << std::setprecision(4) << v;
    return os.str();
  }
  std::vector<float> error_k;
  std::size_t without_truth = 0;
  std::string json() const {
    if (error_k.empty()) return "null";
    std::vector<float> e = error_k;
    double sum = 0.0;
    for (const float v : e) sum += v;
    auto quantile = [&e](double q) {
      const auto at = e.begin() + static_cast<long>(q * static_cast<double>(e.size() - 1));
      std::nth_element(e.begin(), at, e.end());
      return static_cast<double>(*at);
    };
    const double mean = sum / e.size(), median = quantile(0.5), p95 = quantile(0.95);
    std::ostringstream os;
    os << "{\"mean\": " << number(mean) << ", \"median\": " << number(median) << ", \"p95\": " << number(p95)
       << ", \"points\": " << e.size() << ", \"points_without_truth\": " << without_truth;
    // JSON has no inf or nan: such a statistic is null, and says why.
    if (!std::isfinite(mean) || !std::isfinite(median) || !std::isfinite(p95)) {
      os << ", \"null_because\": \"some temperatures are not finite (check the radiometry)\"";
    }
    os << "}";
    return os.str();
  }
};

/// The trajectory of ground_truth.yaml (simulated sessions), if any.
std::optional<Trajectory> ground_truth_trajectory(const std::string& session_dir) {
  const fs::path yaml = fs::path(session_dir) / "ground_truth.yaml";
  if (!fs::exists(yaml)) return std::nullopt;
  const core::YamlField root(core::load_yaml_file(yaml.string()), yaml.string());
  const std::optional<core::YamlField> trajectory = root.find("trajectory");
  if (!trajectory) return std::nullopt;
  fs::path csv = trajectory->as_string("a CSV file of the true trajectory");
  if (csv.is_relative()) csv = fs::path(session_dir) / csv;
  return read_trajectory_csv(csv.string());
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream os;
  os << std::setprecision(6) << v;
  return os.str();
}

/// A JSON string literal: quotes, backslashes and control characters escaped.
std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buffer[8];
      std::snprintf(buffer, sizeof buffer, "\\u%04x", c);
      out += buffer;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

/// Problems found before the long work, listed together (a file can be named many times,
/// e.g. 500 frames of another size: the first few per kind are listed, then a count).
class Preflight {
 public:
  void add(const std::string& file, const std::string& what, const std::string& group = "") {
    const std::string key = group.empty() ? file : group;
    if (++per_group_[key] > kListed) return;
    problems_.push_back(file + ": " + what);
  }
  /// An error a reader threw about `file`: its message already names the file when it
  /// starts with it.
  void add_error(const std::string& file, const std::string& context, const std::exception& e) {
    std::string what = e.what();
    if (what.rfind(file + ": ", 0) == 0) what = what.substr(file.size() + 2);
    add(file, context + ": " + what);
  }
  bool ok() const { return problems_.empty(); }
  std::string report() const {
    std::ostringstream os;
    std::size_t total = 0;
    for (const auto& [group, n] : per_group_) total += n;
    os << "the session has " << total << " problem" << (total == 1 ? "" : "s")
       << " (nothing was written; fix them and run again):";
    for (const std::string& p : problems_) os << "\n  " << p;
    for (const auto& [group, n] : per_group_) {
      if (n > kListed) os << "\n  ... and " << (n - kListed) << " more like the above (" << group << ")";
    }
    return os.str();
  }

 private:
  static constexpr std::size_t kListed = 5;
  std::vector<std::string> problems_;
  std::map<std::string, std::size_t> per_group_;
};

/// Checks a camera's frame files against its camera_info: each exists, is a PNG of the
/// camera's size, and a thermal frame holds 16-bit grey counts (what the radiometry maps).
void check_frames(const std::string& camera, const core::CameraIntrinsics& intrinsics,
                  const std::string& camera_info_path, bool thermal,
                  const std::vector<core::TimedFile>& frames, Preflight* preflight) {
  for (const core::TimedFile& f : frames) {
    std::error_code ec;
    const auto status = fs::status(f.file, ec);
    if (!fs::exists(status)) {
      preflight->add(f.file, "missing (camera '" + camera + "' frame at t=" + std::to_string(f.time_s) + " s)",
                     "camera '" + camera + "' missing frames");
      continue;
    }
    if (!fs::is_regular_file(status)) {
      preflight->add(f.file, "is not a file, expected a PNG frame of camera '" + camera + "'",
                     "camera '" + camera + "' frames that are not files");
      continue;
    }
    core::ImageHeader h;
    try {
      h = core::read_image_header(f.file);
    } catch (const core::Error& e) {
      preflight->add_error(f.file, "camera '" + camera + "' frame", e);
      continue;
    }
    // 8-bit RGB or grey frames; thermal frames hold 16-bit grey raw counts (what the
    // radiometry maps to kelvin).
    std::string mismatch =
        core::image_mismatch(h, intrinsics.width, intrinsics.height, f.file, camera_info_path, thermal ? 16 : 8);
    if (mismatch.empty() && thermal && h.channels != 1) {
      mismatch = f.file + ": has " + std::to_string(h.channels) + " channels, expected 1 (16-bit grey raw counts of " +
                 "thermal camera '" + camera + "')";
    }
    if (!mismatch.empty()) {
      if (mismatch.rfind(f.file + ": ", 0) == 0) mismatch = mismatch.substr(f.file.size() + 2);
      preflight->add(f.file, mismatch + " (camera '" + camera + "')", "camera '" + camera + "' frames that do not match");
    }
  }
}

/// The stage the run reached when Ctrl-C arrived: says what is complete, writes nothing.
int stop_interrupted(const std::string& where, const std::vector<std::string>& written, const std::string& out_dir) {
  std::fprintf(stderr, "rgbdt_mapper: interrupted %s; ", where.c_str());
  if (written.empty()) {
    std::fprintf(stderr, "nothing was written");
  } else {
    std::fprintf(stderr, "complete in %s:", out_dir.c_str());
    for (const std::string& f : written) std::fprintf(stderr, " %s", f.c_str());
  }
  std::fprintf(stderr, "; the other outputs and summary.json (the mark of a complete run) were not written\n");
  return 130;
}

/// What the run has done: stage times, the files complete in OUT and the colour outputs it
/// skips (for summary.json, and for the message when Ctrl-C stops it).
struct Run {
  explicit Run(const std::string& out_dir) : out_dir(out_dir), out(out_dir) {}
  const Clock::time_point start = Clock::now();
  const std::string out_dir;
  const fs::path out;
  std::map<std::string, double> stage_s;
  std::map<std::string, double> colorize_parts_s;  ///< of stage_s["colorize_and_map"]
  std::vector<std::string> written;
  std::map<std::string, std::string>
      not_written;  ///< colour outputs no point gave content, and why

  /// Ctrl-C arrived `where`: says what is complete; the exit code.
  int stop(const std::string& where) const { return stop_interrupted(where, written, out_dir); }
};

constexpr const char* kAbout =
    "rgbdt_mapper: builds an RGB-Depth-Thermal map from a mapping session.\n"
    "Reads the LIDAR from the session's MRPT rawlog (assembled per tilt) or its PCD index,\n"
    "registers the tilt clouds (GICP), colours each point from the RGB and thermal frames\n"
    "nearest in time (motion compensated; points the camera cannot see stay uncoloured;\n"
    "counts -> kelvin through the session's radiometry), and writes map.ply, map.pcd,\n"
    "map.bt, map_rgb.ot, map_thermal.ot, trajectory.csv, PNG renders and summary.json into\n"
    "OUT. For simulated sessions summary.json also scores the trajectory and the thermal\n"
    "colouring against the ground truth.\n"
    "Before any work a preflight checks every file the session names (camera_info,\n"
    "extrinsics, frame indexes, each frame's size and bit depth, the clouds); it lists every\n"
    "problem at once and exits 1 with nothing written. Each output is written whole or not at\n"
    "all; summary.json is written last and marks a complete run. Ctrl-C stops at the next\n"
    "cloud, says which outputs are complete, writes no summary.json and exits 130; a second\n"
    "Ctrl-C ends at once without leaving temporary files.";

/// The command line (bound to CLI11's options: not moved once added).
struct MapperOptions {
  std::string session_path, calib_dir, out_dir, backend = "rgicp", lidar_source = "auto";
  double resolution_m = 0.05;
  int max_clouds = 0;
  std::string motion_prior;
  bool accurate = false;
  bool no_imu = false;
  /// The registration's parameters given on the command line; each replaces the default (or
  /// --accurate's value) only when its option was given.
  RegistrationOptions reg_given;
  CLI::Option *opt_voxel = nullptr, *opt_gate = nullptr, *opt_iterations = nullptr,
              *opt_scale = nullptr, *opt_neighbours = nullptr, *opt_local_map = nullptr,
              *opt_refine = nullptr;
};

void add_options(CLI::App& app, MapperOptions* o) {
  app.add_option("session", o->session_path, "mapping session folder (or its session.yaml)")
      ->required();
  app.add_option("--calib", o->calib_dir,
                 "calibration folder with extrinsics_<camera>.yaml (e.g. SESSION/true_calib)")
      ->required();
  app.add_option("--out", o->out_dir, "output folder (created)")->required();
  app.add_option("--resolution", o->resolution_m, "map voxel and octree resolution [m]")
      ->check(CLI::PositiveNumber);
  app.add_option("--icp", o->backend,
                 "registration back-end: rgicp (ours: GICP's cost with a robust loss), gicp (PCL's "
                 "GICP) or icp (PCL's point-to-point)")
      ->check(CLI::IsMember({"rgicp", "gicp", "icp"}));
  app.add_option("--max-clouds", o->max_clouds, "map only the first N clouds (0: all)");
  app.add_flag("--accurate", o->accurate,
               "LIDAR only (rgicp, gicp): solve the first 4 tilts' motion as one smooth curve, "
               "then every 3rd tilt the last 3 tilts' motion as one smooth curve against the "
               "older ones, on a local map of 24 tilts merged with covariances computed anew, and "
               "a tighter robust loss from the 11th tilt. On 14 simulated 100 m streets the "
               "trajectory error anchored at the first pose fell from 7.7 to 2.9 cm on average "
               "(aligned: 1.8 to 0.4 cm); registration takes ~2x as long (on a quiet host 49 "
               "instead of 26 ms of CPU per 0.6 s tilt, ~55 ms with colour: 10x faster than real "
               "time, every 3rd tilt ~3-4x a plain one). Not with --icp icp; with --motion-prior "
               "only the merged local map applies");
  app.add_option(
         "--motion-prior", o->motion_prior,
         "CSV time_s,x,y,z,qx,qy,qz,qw of the LIDAR's motion from another sensor (IMU or wheel "
         "odometry moved to the LIDAR frame; any fixed frame, any drift): de-skews each tilt and "
         "seeds its registration instead of the constant-velocity guess. Must cover the session's "
         "time.")
      ->check(CLI::ExistingFile);
  app.add_flag("--no-imu", o->no_imu,
               "map without the session's IMU (session.yaml's imu: {samples: imu.csv}, as "
               "rgbdt_import --imu writes it), whose gyro otherwise gives each tilt's rotation for "
               "its de-skew and its registration's guess");
  app.add_option(
         "--lidar", o->lidar_source,
         "LIDAR input: rawlog (lidar.rawlog + tilt_rig.yaml through the assembler), clouds (the "
         "PCD index), or auto (rawlog when the session has both, else clouds)")
      ->check(CLI::IsMember({"auto", "rawlog", "clouds"}));
  // The registration's parameters, over the defaults (or --accurate's values) when given;
  // docs/mapping.md says how each was chosen.
  RegistrationOptions& given = o->reg_given;
  const std::string reg_group = "Registration (default, or --accurate's value, when not given)";
  o->opt_voxel = app.add_option("--source-voxel", given.source_voxel_m,
                                "voxel each cloud is downsampled to before registration [m]")
                     ->check(CLI::PositiveNumber)
                     ->group(reg_group);
  o->opt_gate = app.add_option("--max-correspondence", given.max_correspondence_m,
                               "correspondence gate, above the expected prediction error [m]")
                    ->check(CLI::PositiveNumber)
                    ->group(reg_group);
  o->opt_iterations =
      app.add_option("--max-iterations", given.max_iterations,
                     "correspondence updates (Gauss-Newton steps for rgicp) per registration")
          ->check(CLI::Range(1, 1000))
          ->group(reg_group);
  o->opt_scale =
      app.add_option("--robust-scale2", given.robust_scale2,
                     "rgicp: squared Mahalanobis distance where a correspondence's weight halves")
          ->check(CLI::PositiveNumber)
          ->group(reg_group);
  o->opt_neighbours =
      app.add_option("--covariance-neighbours", given.covariance_neighbours,
                     "rgicp, gicp: neighbours that estimate each point's covariance")
          ->check(CLI::Range(3, 200))
          ->group(reg_group);
  o->opt_local_map = app.add_option("--local-map-clouds", given.local_map_clouds,
                                    "previous clouds that form the local map")
                         ->check(CLI::Range(1, 1000))
                         ->group(reg_group);
  o->opt_refine =
      app.add_option("--refine-above", given.refine_above_m,
                     "de-skew and register a tilt again when its result differs from the "
                     "prediction by more than this (seen at 10 m) [m]")
          ->check(CLI::NonNegativeNumber)
          ->group(reg_group);
}

/// The default registration (or --accurate's), with the parameters given on the command line.
RegistrationOptions registration_options(const MapperOptions& o) {
  RegistrationOptions reg_options =
      o.accurate ? RegistrationOptions::accurate() : RegistrationOptions{};
  reg_options.backend = icp_backend_from_string(o.backend);
  const RegistrationOptions& given = o.reg_given;
  if (o.opt_voxel->count() > 0) reg_options.source_voxel_m = given.source_voxel_m;
  if (o.opt_gate->count() > 0) reg_options.max_correspondence_m = given.max_correspondence_m;
  if (o.opt_iterations->count() > 0) reg_options.max_iterations = given.max_iterations;
  if (o.opt_scale->count() > 0) reg_options.robust_scale2 = given.robust_scale2;
  if (o.opt_neighbours->count() > 0)
    reg_options.covariance_neighbours = given.covariance_neighbours;
  if (o.opt_local_map->count() > 0) reg_options.local_map_clouds = given.local_map_clouds;
  if (o.opt_refine->count() > 0) reg_options.refine_above_m = given.refine_above_m;
  if (const std::string why = reg_options.validate(); !why.empty()) {
    throw std::invalid_argument("registration options: " + why);
  }
  return reg_options;
}

/// The session and what the preflight read of it.
struct SessionInputs {
  core::MappingSession session;
  bool has_rawlog = false;      ///< the session names a rawlog and its rig
  std::string lidar_source;     ///< rawlog or clouds (auto resolved)
  std::vector<Camera> cameras;  ///< those whose intrinsics and extrinsics were read
  std::vector<float> lut_k;     ///< thermal counts -> kelvin (the last thermal camera's)
  std::string radiometry_text;  ///< that radiometry, described
  std::vector<core::TimedFile>
      cloud_index;  ///< --lidar clouds: the first --max-clouds of the index
  std::string imu_used;  ///< the IMU samples whose gyro seeded the tilts, or empty
};

/// A camera's T_camera_lidar from --calib's extrinsics_<camera>.yaml, if readable and finite.
std::optional<Eigen::Isometry3d> read_camera_extrinsics(const std::string& name,
                                                        const std::string& calib_dir,
                                                        Preflight* preflight) {
  const fs::path extrinsics_path = fs::path(calib_dir) / ("extrinsics_" + name + ".yaml");
  std::optional<Eigen::Isometry3d> T_camera_lidar;
  try {
    const Eigen::Isometry3d T =
        core::read_extrinsics(extrinsics_path.string(), core::ExtrinsicsFrames{name})
            .T_parent_child;
    if (!T.matrix().allFinite()) {
      preflight->add(extrinsics_path.string(),
                     "camera '" + name +
                         "': the transform has non-finite values (nan or inf), "
                         "expected finite translation and rotation");
    } else {
      T_camera_lidar = T;
    }
  } catch (const std::exception& e) {
    preflight->add_error(extrinsics_path.string(), "camera '" + name + "' extrinsics", e);
  }
  return T_camera_lidar;
}

/// A camera's frame index (none for a camera without recorded frames).
std::vector<core::TimedFile> read_frame_index(const std::string& name,
                                              const core::CameraEntry& entry,
                                              const std::string& session_dir,
                                              Preflight* preflight) {
  std::vector<core::TimedFile> frames;
  std::error_code ec;
  // `frames: ""` (a camera without recorded frames, as `rgbdt_sim mapping --no-images`
  // writes) reaches here resolved to the session folder itself: a camera that colours
  // nothing, not a folder named by mistake.
  const bool no_frames = entry.frames.empty() || fs::path(entry.frames).lexically_normal() / "" ==
                                                     fs::path(session_dir).lexically_normal() / "";
  if (no_frames) {
    // said below, with the cameras whose index is empty
  } else if (!fs::is_regular_file(entry.frames, ec)) {
    preflight->add(
        entry.frames,
        std::string(fs::is_directory(entry.frames, ec) ? "is a folder" : "does not exist") +
            ", expected camera '" + name + "''s frame index (CSV time_s,file)");
  } else {
    try {
      frames = core::read_time_index(entry.frames);
    } catch (const std::exception& e) {
      preflight->add_error(entry.frames, "camera '" + name + "' frame index", e);
    }
  }
  return frames;
}

/// A thermal camera's radiometry as a counts -> kelvin table, which must be finite for every count.
void read_radiometry(const std::string& name, const core::CameraEntry& entry,
                     const std::string& session_dir, SessionInputs* inputs, Preflight* preflight) {
  try {
    const thermal_camera::Radiometry radiometry = thermal_radiometry(entry, session_dir, name);
    std::vector<float>& lut_k = inputs->lut_k;
    lut_k = radiometry.lookup_table();
    inputs->radiometry_text = radiometry.describe();
    // Temperatures must be numbers: an infinite one (e.g. kelvin_per_count: 1e300) would
    // make every statistic of the map meaningless.
    for (std::size_t c = 0; c < lut_k.size(); ++c) {
      if (std::isinf(lut_k[c])) {
        preflight->add(session_dir + "/session.yaml",
                       "camera '" + name + "' radiometry " + inputs->radiometry_text +
                           " maps count " + std::to_string(c) + " to " +
                           (lut_k[c] > 0 ? "+inf" : "-inf") +
                           " K, expected finite temperatures for every count");
        break;
      }
    }
  } catch (const std::exception& e) {
    std::string what = e.what();  // thermal_radiometry names the session folder
    if (what.rfind(session_dir + ": ", 0) == 0) what = what.substr(session_dir.size() + 2);
    preflight->add(session_dir + "/session.yaml", what);
  }
}

/// Preflight of one camera (intrinsics, extrinsics, frame index, frames, a thermal camera's
/// radiometry); the camera when its intrinsics and extrinsics were read.
std::optional<Camera> preflight_camera(const std::string& name, const core::CameraEntry& entry,
                                       const std::string& calib_dir, SessionInputs* inputs,
                                       Preflight* preflight) {
  const std::string& session_dir = inputs->session.directory;
  std::optional<core::CameraIntrinsics> intrinsics;
  try {
    intrinsics = core::read_camera_info(entry.intrinsics);
  } catch (const std::exception& e) {
    preflight->add_error(entry.intrinsics, "camera '" + name + "' intrinsics", e);
  }
  const std::optional<Eigen::Isometry3d> T_camera_lidar =
      read_camera_extrinsics(name, calib_dir, preflight);
  const bool thermal = name == "thermal" || entry.radiometry.has_value();
  std::vector<core::TimedFile> frames = read_frame_index(name, entry, session_dir, preflight);
  if (intrinsics) check_frames(name, *intrinsics, entry.intrinsics, thermal, frames, preflight);
  if (thermal) read_radiometry(name, entry, session_dir, inputs, preflight);
  if (!intrinsics || !T_camera_lidar) return std::nullopt;
  Camera camera(name, MappedCamera{core::PinholeCamera(*intrinsics), *T_camera_lidar});
  camera.frames = std::move(frames);
  camera.thermal = thermal;
  return camera;
}

/// Preflight of the LIDAR input: the rawlog and its rig, or the cloud index and the PCDs of
/// its first --max-clouds clouds (the index returned).
std::vector<core::TimedFile> preflight_lidar(const SessionInputs& inputs, int max_clouds,
                                             Preflight* preflight) {
  const core::MappingSession& session = inputs.session;
  std::vector<core::TimedFile> cloud_index;
  if (inputs.lidar_source == "rawlog") {
    if (!inputs.has_rawlog) {
      preflight->add(session.directory,
                     "--lidar rawlog needs lidar: {rawlog: FILE, rig: tilt_rig.yaml}");
    } else {
      for (const std::string& f : {session.lidar.rawlog, session.lidar.rig}) {
        std::error_code ec;
        if (!fs::is_regular_file(f, ec))
          preflight->add(f, "does not exist or is not a file (named by lidar:)");
      }
    }
  } else if (session.lidar.clouds.empty()) {
    preflight->add(session.directory,
                   "lidar has neither a rawlog with its rig nor a 'clouds' index "
                   "(expected lidar: {rawlog: lidar.rawlog, rig: tilt_rig.yaml} or "
                   "{clouds: clouds/index.csv})");
  } else {
    std::error_code ec;
    if (!fs::is_regular_file(session.lidar.clouds, ec)) {
      preflight->add(session.lidar.clouds,
                     "does not exist or is not a file, expected the cloud index (CSV "
                     "time_s,file.pcd)");
    } else {
      try {
        cloud_index = core::read_time_index(session.lidar.clouds);
      } catch (const std::exception& e) {
        preflight->add_error(session.lidar.clouds, "cloud index", e);
      }
      if (max_clouds > 0 && static_cast<int>(cloud_index.size()) > max_clouds)
        cloud_index.resize(max_clouds);
      for (const core::TimedFile& f : cloud_index) {
        if (!fs::is_regular_file(f.file, ec)) {
          preflight->add(f.file,
                         std::string(fs::exists(f.file, ec) ? "is not a file" : "missing") +
                             ", expected the PCD of the cloud at t=" + std::to_string(f.time_s) +
                             " s",
                         "missing clouds");
        }
      }
    }
  }
  return cloud_index;
}

/// Reads the session and checks every file it names, before any long work and before OUT is
/// touched; throws with all problems listed together.
SessionInputs read_inputs(const MapperOptions& options) {
  SessionInputs inputs;
  inputs.session = core::read_mapping_session(options.session_path);
  const core::MappingSession& session = inputs.session;
  inputs.has_rawlog = !session.lidar.rawlog.empty() && !session.lidar.rig.empty();
  inputs.lidar_source = options.lidar_source;
  if (inputs.lidar_source == "auto") inputs.lidar_source = inputs.has_rawlog ? "rawlog" : "clouds";
  Preflight preflight;
  for (const auto& [name, entry] : session.cameras) {
    std::optional<Camera> camera =
        preflight_camera(name, entry, options.calib_dir, &inputs, &preflight);
    if (camera) inputs.cameras.push_back(std::move(*camera));
  }
  inputs.cloud_index = preflight_lidar(inputs, options.max_clouds, &preflight);
  if (!preflight.ok()) throw core::Error(session.directory, preflight.report());
  return inputs;
}

/// The tilt clouds to map and, for summary.json, the assembler's counts.
struct LidarClouds {
  std::vector<TiltSource> clouds;
  std::string assembler_json = "null";
};

/// The first --max-clouds tilt clouds: assembled from the rawlog, or the cloud index's PCDs.
LidarClouds read_lidar(const SessionInputs& inputs, int max_clouds, Run* run) {
  const core::MappingSession& session = inputs.session;
  LidarClouds lidar;
  std::vector<TiltSource>& clouds = lidar.clouds;
  const auto t0 = Clock::now();
  if (inputs.lidar_source == "rawlog") {
    std::printf("rgbdt_mapper: assembling %s\n", session.lidar.rawlog.c_str());
    std::fflush(stdout);
    clouds = assemble_rawlog(session, &lidar.assembler_json);
  } else {
    for (const core::TimedFile& f : inputs.cloud_index)
      clouds.push_back({f.time_s, f.file, nullptr});
  }
  run->stage_s["lidar_input"] = seconds_since(t0);
  if (max_clouds > 0 && static_cast<int>(clouds.size()) > max_clouds) clouds.resize(max_clouds);
  if (clouds.size() < 2) {
    throw core::Error(inputs.lidar_source == "rawlog" ? session.lidar.rawlog : session.lidar.clouds,
                      "needs at least 2 tilt clouds, found " + std::to_string(clouds.size()));
  }
  return lidar;
}

/// What will be mapped: the clouds, the cameras (saying which colour nothing) and the radiometry.
void print_inputs(const SessionInputs& inputs, const std::vector<TiltSource>& clouds) {
  // A camera whose frames do not overlap the LIDAR's time colours nothing: valid, but say so.
  for (const Camera& c : inputs.cameras) {
    const double lidar_begin = clouds.front().time_s,
                 lidar_end = clouds.back().time_s + kMaxFrameGapS;
    if (c.frames.empty()) {
      std::printf("rgbdt_mapper: camera '%s' has no frames: no point takes its %s\n",
                  c.name.c_str(), c.thermal ? "temperature" : "colour");
    } else if (c.frames.back().time_s < lidar_begin - kMaxFrameGapS ||
               c.frames.front().time_s > lidar_end) {
      std::printf(
          "rgbdt_mapper: camera '%s' frames span %.3f - %.3f s, outside the LIDAR's %.3f - %.3f s: "
          "no point takes its %s\n",
          c.name.c_str(), c.frames.front().time_s, c.frames.back().time_s, lidar_begin,
          clouds.back().time_s, c.thermal ? "temperature" : "colour");
    }
  }
  std::printf("rgbdt_mapper: %zu clouds (%s), cameras:", clouds.size(),
              inputs.lidar_source.c_str());
  for (const auto& c : inputs.cameras)
    std::printf(" %s (%zu frames)", c.name.c_str(), c.frames.size());
  if (!inputs.radiometry_text.empty())
    std::printf("; thermal radiometry %s", inputs.radiometry_text.c_str());
  std::printf("\n");
}

/// Throws naming `file` unless its `count` (>= 2) records from first_s to last_s cover the
/// clouds' time; `hint` ends the message.
void require_covers_clouds(const std::string& file, double first_s, double last_s, std::size_t count,
                           const std::vector<TiltSource>& clouds, const std::string& hint) {
  if (count >= 2 && first_s <= clouds.front().time_s && last_s >= clouds.back().time_s) return;
  throw core::Error(file, "covers " +
                              (count == 0 ? std::string("no time")
                                          : std::to_string(first_s) + " - " + std::to_string(last_s) + " s") +
                              ", expected at least the clouds' " + std::to_string(clouds.front().time_s) +
                              " - " + std::to_string(clouds.back().time_s) + " s" + hint);
}

/// --motion-prior, when given: must cover the clouds' time; it then de-skews and seeds each tilt.
void use_motion_prior(const MapperOptions& options, const std::vector<TiltSource>& clouds,
                      Odometry* odometry) {
  const std::string& motion_prior = options.motion_prior;
  if (motion_prior.empty()) return;
  if (options.accurate) {
    std::printf(
        "rgbdt_mapper: --accurate with --motion-prior: the prior de-skews each tilt, so only the "
        "merged local map applies (the smooth start-up and windows are for LIDAR only)\n");
  }
  Trajectory prior = read_trajectory_csv(motion_prior);
  require_covers_clouds(motion_prior, prior.empty() ? 0.0 : prior.poses().front().time_s,
                        prior.empty() ? 0.0 : prior.poses().back().time_s, prior.size(), clouds, "");
  std::printf("motion prior: %s (%zu poses)\n", motion_prior.c_str(), prior.size());
  odometry->set_motion_prior(std::move(prior));
}

/// The session's IMU, unless --no-imu or --motion-prior: its gyro's rotation de-skews and seeds
/// each tilt (Odometry::set_rotation_prior). The samples must cover the clouds' time. Returns
/// the samples' file, or "" when the IMU is not used.
std::string use_imu(const MapperOptions& options, const core::MappingSession& session,
                    const std::vector<TiltSource>& clouds, Odometry* odometry) {
  if (!session.imu) return "";
  const std::string& file = session.imu->samples;
  if (options.no_imu || !options.motion_prior.empty()) {
    std::printf("IMU: %s not used (%s)\n", file.c_str(),
                options.no_imu ? "--no-imu" : "--motion-prior gives the motion");
    return "";
  }
  const std::vector<ImuSample> samples = read_imu_csv(file);
  require_covers_clouds(file, samples.empty() ? 0.0 : samples.front().time_s,
                        samples.empty() ? 0.0 : samples.back().time_s, samples.size(), clouds,
                        " (or map with --no-imu)");
  const double span_s = samples.back().time_s - samples.front().time_s;
  std::printf("IMU: %s (%zu samples, %.0f Hz): the gyro's rotation de-skews and seeds each tilt\n",
              file.c_str(), samples.size(), double(samples.size() - 1) / span_s);
  if (const double gap_s = largest_imu_gap_s(samples); gap_s > 0.05) {
    std::printf("IMU: warning: samples %.3f s apart at most; the rotation across a gap assumes a "
                "constant rate\n", gap_s);
  }
  odometry->set_rotation_prior(gyro_rotation_track(samples, session.imu->rotation_lidar_imu));
  return file;
}

/// OUT: the completion marker of an earlier run goes first, then every file this run
/// writes (colour outputs it may skip included), so OUT never mixes two runs.
void clear_outputs(const fs::path& out) {
  const std::vector<std::string> output_names = {"summary.json",
                                                 "trajectory.csv",
                                                 "map.ply",
                                                 "map.pcd",
                                                 "map.bt",
                                                 "map_rgb.ot",
                                                 "map_thermal.ot",
                                                 "render_rgb_top.png",
                                                 "render_rgb_perspective.png",
                                                 "render_thermal_top.png",
                                                 "render_thermal_perspective.png"};
  fs::create_directories(out);
  for (const std::string& name : output_names) core::remove_stale_output((out / name).string());
}

/// Registration's counts, for its report and summary.json.
struct RegistrationTotals {
  std::size_t points = 0, not_converged = 0;
  double icp_ms = 0.0;
};

/// Stage 1: every cloud through the odometry, progress printed. The exit code when Ctrl-C stopped
/// it.
std::optional<int> register_clouds(const std::vector<TiltSource>& clouds, Odometry* odometry,
                                   RegistrationTotals* totals, Run* run) {
  const auto t0 = Clock::now();
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    if (core::interrupted()) {
      return run->stop("during the registration, before cloud " + std::to_string(k + 1) + "/" +
                       std::to_string(clouds.size()));
    }
    const cloud::LoadedCloud loaded = clouds[k].load();
    totals->points += loaded.cloud->size();
    const Odometry::Step step = odometry->add(*loaded.cloud, clouds[k].time_s);
    totals->icp_ms += step.registration.time_ms;
    if (step.registered && !step.registration.converged) {
      // The pose is kept (the last step's, or the guess when nothing matched): say so.
      ++totals->not_converged;
      std::printf(
          "[register %zu/%zu] t=%.2f s: registration did not converge (%d iterations, %zu of %zu "
          "points); its pose is kept\n",
          k + 1, clouds.size(), clouds[k].time_s, step.registration.iterations,
          step.registration.source_points, loaded.cloud->size());
    }
    if (k % 10 == 0 || k + 1 == clouds.size()) {
      const Eigen::Vector3d p = step.T_world_lidar.translation();
      std::printf(
          "[register %zu/%zu] t=%.2f s  %zu points  pose (%.2f, %.2f, %.2f) m  icp %.0f ms\n",
          k + 1, clouds.size(), clouds[k].time_s, loaded.cloud->size(), p.x(), p.y(), p.z(),
          step.registration.time_ms);
      std::fflush(stdout);
    }
  }
  run->stage_s["registration"] = seconds_since(t0);
  return std::nullopt;
}

/// What registration did beyond tilt by tilt: registrations that did not converge, the first
/// tilt registered again, the smooth start-up and the windows solved again.
void report_registration(const Odometry& odometry, const RegistrationOptions& reg_options,
                         const RegistrationTotals& totals, std::size_t clouds) {
  if (totals.not_converged > 0) {
    std::printf("rgbdt_mapper: %zu of %zu registrations did not converge (listed above)\n",
                totals.not_converged, clouds - 1);
  }
  const Odometry::Reanchoring& reanchoring = odometry.reanchoring();
  if (reanchoring.attempted) {
    const Eigen::Isometry3d& C = reanchoring.correction;
    std::printf(
        "rgbdt_mapper: first tilt registered again against the tilts that followed: correction "
        "%.3f m, %.3f deg, %s\n",
        C.translation().norm(), Eigen::AngleAxisd(C.linear()).angle() * 180.0 / M_PI,
        reanchoring.applied
            ? "applied"
            : "NOT applied (did not converge or beyond the correspondence gate); the "
              "start-up poses are kept");
  }
  const Odometry::StartUp& start_up = odometry.start_up();
  if (start_up.attempted) {
    std::printf(
        "rgbdt_mapper: the first %d tilts solved again as one smooth motion (%d steps, %.0f ms): "
        "%s\n",
        reg_options.start_up_clouds, start_up.iterations, start_up.time_ms,
        start_up.applied ? "applied"
                         : "NOT applied (did not converge or beyond the correspondence gate); the "
                           "poses registered one by one are kept");
  }
  const Odometry::Window& window = odometry.window();
  if (window.solves > 0) {
    std::printf(
        "rgbdt_mapper: %d windows of %d tilts (one every %d tilts) solved again as smooth motions "
        "(%d steps, %.1f s); %d did not converge and kept their poses\n",
        window.solves, reg_options.window_clouds, reg_options.window_interval_clouds,
        window.iterations, window.time_ms / 1000.0, window.not_converged);
  }
}

/// OUT/trajectory.csv: trajectory.hpp's CSV layout, written atomically.
void write_trajectory(const Trajectory& trajectory, Run* run) {
  std::ostringstream csv;
  csv << "time_s,x,y,z,qx,qy,qz,qw\n" << std::setprecision(10);
  for (const auto& p : trajectory.poses()) {
    const Eigen::Vector3d t = p.T_world_lidar.translation();
    const Eigen::Vector4d q =
        core::quaternion_to_xyzw(Eigen::Quaterniond(p.T_world_lidar.rotation()));
    csv << p.time_s << ',' << t.x() << ',' << t.y() << ',' << t.z() << ',' << q[0] << ',' << q[1]
        << ',' << q[2] << ',' << q[3] << '\n';
  }
  core::write_file_atomic((run->out / "trajectory.csv").string(), csv.str());
  run->written.push_back("trajectory.csv");
}

OccupancyOptions occupancy_at(double resolution_m) {
  OccupancyOptions occupancy_options;
  occupancy_options.resolution_m = resolution_m;
  return occupancy_options;
}

/// Stage 2's maps: the coloured voxel map (one thermal layer, named after the session) and
/// the ray-inserted occupancy.
struct Maps {
  Maps(double resolution_m, const std::string& session_dir)
      : voxels({resolution_m}),
        layer(voxels.add_thermal_layer(fs::path(session_dir).filename().string())),
        occupancy(occupancy_at(resolution_m)) {}
  VoxelMap voxels;
  const int layer;
  OccupancyMapBuilder occupancy;
};

/// What colours the clouds: the cameras, the thermal counts -> kelvin table, the trajectory
/// that moves points to a frame's time and (simulated sessions) the true temperatures the
/// coloured points are scored against.
struct Colouring {
  std::vector<Camera>& cameras;
  const std::vector<float>& lut_k;
  const Trajectory& trajectory;
  const std::optional<BeamTemperatureTruth>& temperature_truth;
  ThermalErrors thermal_errors;
  double truth_s = 0.0;  ///< time spent scoring against the truth
};

/// A cloud's colours: the first RGB camera's, and a thermal camera's temperatures.
struct CloudColours {
  std::optional<RgbColors> rgb;
  std::optional<Temperatures> temps;
};

/// The errors of a cloud's coloured temperatures against the truth.
void score_temperatures(const cloud::Cloud& cloud, double time_s, const Temperatures& temps,
                        Colouring* colouring) {
  const auto tt = Clock::now();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (temps.status[i] != ColorStatus::kColored) continue;
    const double truth = colouring->temperature_truth->kelvin_at(time_s + cloud[i].t);
    if (std::isnan(truth)) {
      ++colouring->thermal_errors.without_truth;
    } else {
      colouring->thermal_errors.error_k.push_back(
          static_cast<float>(std::abs(temps.temperature_k[i] - truth)));
    }
  }
  colouring->truth_s += seconds_since(tt);
}

/// Colours a cloud from each camera's frame nearest its middle (none when further than
/// kMaxFrameGapS), occlusion aware; counts each camera's statistics.
CloudColours colour_cloud(const cloud::LoadedCloud& loaded, double time_s, double mid_time_s,
                          Colouring* colouring) {
  const cloud::Cloud& cloud = *loaded.cloud;
  CloudColours colours;
  for (Camera& camera : colouring->cameras) {
    const int frame = core::nearest_in_time(camera.frames, mid_time_s);
    // No frame near the cloud's time: its points stay without this camera's colour.
    if (frame < 0 || std::abs(camera.frames[frame].time_s - mid_time_s) > kMaxFrameGapS) {
      ++camera.clouds_without_frame;
      continue;
    }
    const core::TimedFile& file = camera.frames[frame];
    const CameraProjection projection =
        project_with_occlusion(cloud, loaded.has_ring && loaded.has_t, time_s, camera.mapped,
                               file.time_s, &colouring->trajectory);
    for (const ColorStatus s : projection.status) {
      camera.in_view += s == ColorStatus::kColored || s == ColorStatus::kOccluded;
      camera.occluded += s == ColorStatus::kOccluded;
    }
    if (camera.thermal) {
      colours.temps = sample_temperature(projection, camera.load(file.file), colouring->lut_k);
      camera.colored += colours.temps->colored;
      if (colouring->temperature_truth)
        score_temperatures(cloud, time_s, *colours.temps, colouring);
    } else if (!colours.rgb) {
      colours.rgb = sample_rgb(projection, camera.load(file.file));
      camera.colored += colours.rgb->colored;
    }
  }
  return colours;
}

/// Ray insertion from where the sensor was: one origin per 100 ms of the tilt (the cart
/// moves ~0.1 m in that time, below the free-space precision that matters).
void insert_rays(const cloud::Cloud& cloud, const std::vector<Eigen::Vector3f>& world,
                 double time_s, const Trajectory& trajectory, OccupancyMapBuilder* occupancy) {
  constexpr double kChunkS = 0.1;
  std::map<long long, std::vector<Eigen::Vector3f>> chunks;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    chunks[static_cast<long long>(cloud[i].t / kChunkS)].push_back(world[i]);
  }
  for (const auto& [chunk, points] : chunks) {
    const double t = time_s + (chunk + 0.5) * kChunkS;
    occupancy->insert_scan(points, trajectory.pose_at(t).translation());
  }
}

/// Stage 2: every cloud coloured into the voxel map and ray-inserted into the occupancy,
/// progress printed. The exit code when Ctrl-C stopped it.
std::optional<int> colour_and_map(const std::vector<TiltSource>& clouds, Colouring* colouring,
                                  Maps* maps, Run* run) {
  double colorize_s = 0.0, occupancy_s = 0.0, voxel_map_s = 0.0;
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    if (core::interrupted()) {
      return run->stop("while colouring and mapping, before cloud " + std::to_string(k + 1) + "/" +
                       std::to_string(clouds.size()));
    }
    const cloud::LoadedCloud loaded = clouds[k].load();
    const cloud::Cloud& cloud = *loaded.cloud;
    float t_max = 0.0f;
    for (const auto& p : cloud) t_max = std::max(t_max, p.t);
    const double mid_time_s = clouds[k].time_s + 0.5 * t_max;

    const auto tc = Clock::now();
    const CloudColours colours = colour_cloud(loaded, clouds[k].time_s, mid_time_s, colouring);
    const auto tv = Clock::now();
    const std::vector<Eigen::Vector3f> world =
        points_in_world(cloud, clouds[k].time_s, colouring->trajectory);
    maps->voxels.insert(world, colours.rgb ? &*colours.rgb : nullptr,
                        colours.temps ? &*colours.temps : nullptr, maps->layer, mid_time_s);
    voxel_map_s += seconds_since(tv);
    colorize_s += seconds_since(tc);

    const auto to = Clock::now();
    insert_rays(cloud, world, clouds[k].time_s, colouring->trajectory, &maps->occupancy);
    occupancy_s += seconds_since(to);
    if (k % 10 == 0 || k + 1 == clouds.size()) {
      std::printf("[map %zu/%zu] %zu voxels\n", k + 1, clouds.size(), maps->voxels.size());
      std::fflush(stdout);
    }
  }
  run->stage_s["colorize_and_map"] = colorize_s;
  // Its parts: what a live rig would not pay (decoding the recorded PNGs, checking against
  // the simulator's truth) apart from the colouring itself and the voxel map.
  double decode_s = 0.0;
  for (const Camera& camera : colouring->cameras) decode_s += camera.decode_s;
  run->colorize_parts_s["image_decode"] = decode_s;
  run->colorize_parts_s["thermal_truth_check"] = colouring->truth_s;
  run->colorize_parts_s["voxel_map"] = voxel_map_s;
  run->colorize_parts_s["colour"] = colorize_s - decode_s - colouring->truth_s - voxel_map_s;
  run->stage_s["octomap_occupancy"] = occupancy_s;
  return std::nullopt;
}

/// The colour outputs that would be empty (no point took that colour), and why.
std::map<std::string, std::string> outputs_without_colour(const std::vector<MapPoint>& points,
                                                          const std::vector<Camera>& cameras) {
  const bool any_rgb =
      std::any_of(points.begin(), points.end(), [](const MapPoint& p) { return p.has_rgb; });
  const bool any_temperature = std::any_of(points.begin(), points.end(), [](const MapPoint& p) {
    return std::isfinite(p.temperature_k);
  });
  std::map<std::string, std::string> not_written;
  auto why_no_colour = [&](bool thermal) -> std::string {
    const bool has_camera = std::any_of(cameras.begin(), cameras.end(),
                                        [&](const Camera& c) { return c.thermal == thermal; });
    if (!has_camera)
      return thermal ? "no thermal camera in the session" : "no RGB camera in the session";
    return thermal ? "no point took a temperature (no thermal frame near the clouds' times, or "
                     "none saw them)"
                   : "no point took an RGB colour (no RGB frame near the clouds' times, or none "
                     "saw them)";
  };
  if (!any_rgb) {
    for (const char* name : {"map_rgb.ot", "render_rgb_top.png", "render_rgb_perspective.png"}) {
      not_written[name] = why_no_colour(false);
    }
  }
  if (!any_temperature) {
    for (const char* name :
         {"map_thermal.ot", "render_thermal_top.png", "render_thermal_perspective.png"}) {
      not_written[name] = why_no_colour(true);
    }
  }
  return not_written;
}

/// Stage 3: the map files and renders, each timed into its stage; colour outputs only where
/// some point took that colour. The exit code when Ctrl-C stopped it.
std::optional<int> write_map_files(const std::vector<MapPoint>& points, double resolution_m,
                                   OccupancyMapBuilder* occupancy, Run* run) {
  const fs::path& out = run->out;
  RenderOptions render_options;
  render_options.voxel_size_m = resolution_m;
  auto write_png = [&](const std::string& name, const cv::Mat& image) {
    const std::string path = (out / name).string();
    std::vector<unsigned char> png;
    if (image.empty() || !cv::imencode(".png", image, png))
      throw core::Error(path, "cannot encode the render as PNG");
    core::write_file_atomic(
        path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  };
  const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> exports = {
      {"map.ply", [&](const std::string& path) { write_ply(path, points); }},
      {"map.pcd", [&](const std::string& path) { write_pcd(path, points); }},
      {"map.bt", [&](const std::string& path) { occupancy->write_bt(path); }},
      {"map_rgb.ot",
       [&](const std::string& path) { write_color_octree(path, points, resolution_m); }},
      {"map_thermal.ot",
       [&](const std::string& path) { write_thermal_octree(path, points, resolution_m); }},
      {"render_rgb_top.png",
       [&](const std::string&) {
         write_png("render_rgb_top.png", render_top_view(points, RenderMode::kRgb, render_options));
       }},
      {"render_rgb_perspective.png",
       [&](const std::string&) {
         write_png("render_rgb_perspective.png",
                   render_perspective(points, RenderMode::kRgb, render_options));
       }},
      {"render_thermal_top.png",
       [&](const std::string&) {
         write_png("render_thermal_top.png",
                   render_top_view(points, RenderMode::kThermal, render_options));
       }},
      {"render_thermal_perspective.png",
       [&](const std::string&) {
         write_png("render_thermal_perspective.png",
                   render_perspective(points, RenderMode::kThermal, render_options));
       }},
  };
  for (const auto& [name, write] : exports) {
    if (run->not_written.count(name)) continue;
    if (core::interrupted()) return run->stop("before writing " + name);
    std::printf("rgbdt_mapper: writing %s\n", name.c_str());
    std::fflush(stdout);
    const auto t0 = Clock::now();
    write((out / name).string());
    const double s = seconds_since(t0);
    run->stage_s[name.rfind("render_", 0) == 0            ? "render"
                 : name == "map.ply" || name == "map.pcd" ? "export_ply_pcd"
                                                          : "export_octomap"] += s;
    run->written.push_back(name);
  }
  return std::nullopt;
}

/// The trajectory's error against the truth (ground_truth.yaml, else the session's
/// trajectory), when there is one.
struct TrajectoryScore {
  std::optional<double> rmse, ate;
};

TrajectoryScore score_trajectory(const Trajectory& trajectory,
                                 const core::MappingSession& session) {
  TrajectoryScore score;
  std::optional<Trajectory> truth = ground_truth_trajectory(session.directory);
  if (!truth && !session.trajectory.empty()) truth = read_trajectory_csv(session.trajectory);
  if (truth) {
    score.rmse = trajectory_rmse_m(trajectory, *truth);
    if (trajectory.size() >= 3) score.ate = trajectory_ate_m(trajectory, *truth);
  }
  return score;
}

/// summary.json's cameras: each one's coloured points; then the first RGB camera's fraction.
void json_cameras(const std::vector<Camera>& cameras, std::size_t total_points,
                  std::ostringstream& json) {
  double rgb_fraction = NAN;
  for (const Camera& c : cameras) {
    const double fraction = static_cast<double>(c.colored) / std::max<std::size_t>(1, total_points);
    const double in_view = static_cast<double>(c.colored) / std::max<std::size_t>(1, c.in_view);
    if (!c.thermal && std::isnan(rgb_fraction)) rgb_fraction = fraction;
    json << ",\n  \"" << c.name << "\": {\"colored_points\": " << c.colored
         << ", \"colored_fraction\": " << json_number(fraction)
         << ", \"colored_fraction_in_view\": " << json_number(in_view)
         << ", \"occluded_points\": " << c.occluded
         << ", \"clouds_without_frame\": " << c.clouds_without_frame << "}";
  }
  json << ",\n  \"colored_fraction\": " << json_number(rgb_fraction);
}

/// A JSON object of named seconds, in the map's order.
void json_seconds(const std::map<std::string, double>& seconds, std::ostringstream& json) {
  bool first = true;
  for (const auto& [name, s] : seconds) {
    json << (first ? "" : ", ") << "\"" << name << "\": " << json_number(s);
    first = false;
  }
}

/// summary.json's registration: what it ran with, --accurate's values included.
std::string json_registration(const RegistrationOptions& reg_options) {
  std::ostringstream json;
  json << "{\"backend\": \"" << to_string(reg_options.backend)
       << "\", \"source_voxel_m\": " << json_number(reg_options.source_voxel_m)
       << ", \"max_correspondence_m\": " << json_number(reg_options.max_correspondence_m)
       << ", \"max_iterations\": " << reg_options.max_iterations
       << ", \"robust_scale2\": " << json_number(reg_options.robust_scale2)
       << ", \"covariance_neighbours\": " << reg_options.covariance_neighbours
       << ", \"local_map_clouds\": " << reg_options.local_map_clouds
       << ", \"refine_above_m\": " << json_number(reg_options.refine_above_m) << "}";
  return json.str();
}

/// summary.json's outputs (summary.json itself included) and the outputs not written, with why.
void json_outputs(const Run& run, std::ostringstream& json) {
  json << ",\n  \"outputs\": [";
  for (std::size_t i = 0; i < run.written.size(); ++i)
    json << (i ? ", " : "") << json_string(run.written[i]);
  json << ", \"summary.json\"],\n  \"outputs_not_written\": {";
  bool first = true;
  for (const auto& [name, why] : run.not_written) {
    json << (first ? "" : ", ") << json_string(name) << ": " << json_string(why);
    first = false;
  }
  json << "}\n}\n";
}

/// summary.json: counts, coloured fractions, trajectory and thermal errors, stage times, the
/// effective configuration and registration, the outputs.
std::string summary_json(const CLI::App& app, const MapperOptions& options,
                         const SessionInputs& inputs, const LidarClouds& lidar,
                         const Odometry& odometry, const RegistrationOptions& reg_options,
                         const RegistrationTotals& totals, const Maps& maps,
                         const Colouring& colouring, const TrajectoryScore& score, const Run& run) {
  const std::size_t clouds = lidar.clouds.size();
  std::ostringstream json;
  json << "{\n  \"clouds\": " << clouds << ",\n  \"points\": " << totals.points
       << ",\n  \"voxels\": " << maps.voxels.size()
       << ",\n  \"resolution_m\": " << json_number(options.resolution_m)
       << ",\n  \"icp_backend\": \"" << options.backend
       << "\",\n  \"registrations_not_converged\": " << totals.not_converged
       << ",\n  \"first_tilt_reanchored\": " << (odometry.reanchoring().applied ? "true" : "false")
       << ",\n  \"smooth_start_up\": " << (odometry.start_up().applied ? "true" : "false")
       << ",\n  \"merged_local_map_m\": " << reg_options.merged_local_map_m
       << ",\n  \"window_solves\": " << odometry.window().solves << ",\n  \"icp_mean_ms\": "
       << json_number(totals.icp_ms / std::max<std::size_t>(1, clouds - 1));
  json_cameras(inputs.cameras, totals.points, json);
  json << ",\n  \"trajectory_rmse_m\": " << (score.rmse ? json_number(*score.rmse) : "null");
  json << ",\n  \"trajectory_ate_m\": " << (score.ate ? json_number(*score.ate) : "null");
  json << ",\n  \"motion_prior\": "
       << (options.motion_prior.empty() ? std::string("null") : json_string(options.motion_prior));
  json << ",\n  \"imu\": "
       << (inputs.imu_used.empty() ? std::string("null") : json_string(inputs.imu_used));
  json << ",\n  \"thermal_error_k\": " << colouring.thermal_errors.json();
  json << ",\n  \"lidar_source\": \"" << inputs.lidar_source << "\"";
  json << ",\n  \"assembler\": " << lidar.assembler_json;
  json << ",\n  \"time_s\": {";
  json_seconds(run.stage_s, json);
  json << ", \"total\": " << json_number(seconds_since(run.start)) << "}";
  json << ",\n  \"colorize_and_map_parts_s\": {";
  json_seconds(run.colorize_parts_s, json);
  json << "}";
  json << ",\n  \"config\": " << rgbdt::apps::effective_config_json(app);
  json << ",\n  \"registration\": " << json_registration(reg_options);
  json_outputs(run, json);
  return json.str();
}

/// The rate that matters on a rig: registering and colouring a tilt against the time the
/// tilts took to record (reading the recorded images is apart: a live camera delivers them).
void print_rates(const std::vector<TiltSource>& clouds, double icp_ms, const Run& run) {
  if (clouds.size() < 2) return;
  const double n = static_cast<double>(clouds.size());
  const double per_tilt_s = (clouds.back().time_s - clouds.front().time_s) / (n - 1.0);
  const double register_ms = icp_ms / n, colour_ms = 1e3 * run.colorize_parts_s.at("colour") / n;
  std::printf(
      "\nper tilt (every %.2f s): registration %.1f ms + colour %.1f ms = %.1f ms, %.1fx faster "
      "than the tilts came; also reading the images %.1f ms, voxel map %.1f ms, occupancy %.1f "
      "ms\n",
      per_tilt_s, register_ms, colour_ms, register_ms + colour_ms,
      1e3 * per_tilt_s / (register_ms + colour_ms),
      1e3 * run.colorize_parts_s.at("image_decode") / n,
      1e3 * run.colorize_parts_s.at("voxel_map") / n,
      1e3 * run.stage_s.at("octomap_occupancy") / n);
}

/// The files written into OUT, and those not written with why.
void print_outputs(const Run& run) {
  std::printf("\nwrote %s/{", run.out_dir.c_str());
  for (std::size_t i = 0; i < run.written.size(); ++i)
    std::printf("%s%s", i ? ", " : "", run.written[i].c_str());
  std::printf("}\n");
  for (const auto& [name, why] : run.not_written)
    std::printf("not written: %s (%s)\n", name.c_str(), why.c_str());
}

/// The map of the session: preflight, LIDAR input, registration, colouring and the files.
/// The exit code (130 when Ctrl-C stopped it).
int map_session(const CLI::App& app, const MapperOptions& options) {
  Run run(options.out_dir);
  SessionInputs inputs = read_inputs(options);
  const LidarClouds lidar = read_lidar(inputs, options.max_clouds, &run);
  const std::vector<TiltSource>& clouds = lidar.clouds;
  const std::optional<BeamTemperatureTruth> temperature_truth =
      BeamTemperatureTruth::load(inputs.session.directory);
  print_inputs(inputs, clouds);

  // Stage 1: registration.
  const RegistrationOptions reg_options = registration_options(options);
  Odometry odometry(reg_options);
  use_motion_prior(options, clouds, &odometry);
  inputs.imu_used = use_imu(options, inputs.session, clouds, &odometry);
  clear_outputs(run.out);
  RegistrationTotals totals;
  if (const std::optional<int> stopped = register_clouds(clouds, &odometry, &totals, &run))
    return *stopped;
  report_registration(odometry, reg_options, totals, clouds.size());
  const Trajectory& trajectory = odometry.trajectory();
  write_trajectory(trajectory, &run);

  // Stage 2: colouring, voxel map, occupancy.
  Maps maps(options.resolution_m, inputs.session.directory);
  Colouring colouring{inputs.cameras, inputs.lut_k, trajectory, temperature_truth, {}};
  if (const std::optional<int> stopped = colour_and_map(clouds, &colouring, &maps, &run))
    return *stopped;

  // Stage 3: files. Colour outputs only where some point took that colour.
  const std::vector<MapPoint> points = maps.voxels.points(maps.layer);
  run.not_written = outputs_without_colour(points, inputs.cameras);
  if (const std::optional<int> stopped =
          write_map_files(points, options.resolution_m, &maps.occupancy, &run)) {
    return *stopped;
  }
  const TrajectoryScore score = score_trajectory(trajectory, inputs.session);

  // Summary: written last, the mark of a complete run.
  const std::string summary = summary_json(app, options, inputs, lidar, odometry, reg_options,
                                           totals, maps, colouring, score, run);
  if (core::interrupted()) return run.stop("before writing summary.json");
  core::write_file_atomic((run.out / "summary.json").string(), summary);
  run.written.push_back("summary.json");
  std::printf("\n%s", summary.c_str());
  print_rates(clouds, totals.icp_ms, run);
  print_outputs(run);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{kAbout};
  rgbdt::apps::add_config_option(app, argc, argv);
  MapperOptions options;
  add_options(app, &options);
  CLI11_PARSE(app, argc, argv);
  if (options.accurate && options.backend == "icp") {
    std::fprintf(
        stderr,
        "rgbdt_mapper: --accurate needs GICP's covariances: --icp rgicp (the default) or gicp, "
        "not icp\n");
    return 2;
  }
  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(core::LogLevel::kWarning);
  core::install_interrupt_handler();
  // A file size limit makes a write fail (EFBIG) like a full disk, reported naming the
  // file, instead of ending the process with SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    return map_session(app, options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_mapper: error: %s\n", e.what());
    return 1;
  }
}
