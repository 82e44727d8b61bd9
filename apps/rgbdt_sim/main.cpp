// rgbdt_sim: writes simulated sessions (calibration, checkerboard, mapping, coloring
// setup) with their ground truth, in the formats of design.md and contracts.md.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <exception>
#include <string>

#include "app_config.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/sim/calibration_session.hpp"
#include "rgbdt/sim/checkerboard_session.hpp"
#include "rgbdt/sim/mapping_session.hpp"

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// `rgbdt_sim calibration`: the circle-hole target at varied poses.
struct CalibrationCommand {
  rgbdt::sim::CalibrationSessionOptions options;
  std::string out, lidar = "tilt";
  bool night = false, no_mixed = false;
  CLI::App* cmd = nullptr;

  void add_to(CLI::App& app) {
    cmd = app.add_subcommand(
        "calibration",
        "Circle-hole target (white board, 1 or 4 holes) in front of a wet black cloth at varied "
        "poses 3-8 m: "
        "one assembled LIDAR tilt (clouds/NNN.pcd), one RGB (rgb/NNN.png) and one thermal image "
        "(thermal/NNN.png, 16-bit counts) per view, session.yaml, ground_truth.yaml, true_calib/.");
    cmd->add_option("--out", out, "Output folder (created)")->required();
    cmd->add_option("--views", options.views, "Number of target placements")->capture_default_str();
    cmd->add_option("--seed", options.seed, "Random seed (same seed, same session)")
        ->capture_default_str();
    cmd->add_option(
           "--noise", options.noise_scale,
           "Noise multiplier for LIDAR range sigma (0.01 m), image noise and NETD (0.05 K)")
        ->capture_default_str();
    cmd->add_option("--holes", options.holes,
                    "Holes in the target: 1 (r 0.30 m) or 4 (2x2, r 0.12 m)")
        ->capture_default_str();
    cmd->add_option("--radius", options.hole_radius_m, "Hole radius [m]; 0 = default for --holes")
        ->capture_default_str();
    cmd->add_option("--min-distance", options.min_distance_m, "Nearest board distance [m]")
        ->capture_default_str();
    cmd->add_option("--max-distance", options.max_distance_m, "Farthest board distance [m]")
        ->capture_default_str();
    cmd->add_option("--supersampling", options.supersampling, "N x N sub-samples per edge pixel")
        ->capture_default_str();
    cmd->add_option("--tilt-duration", options.tilt_duration_s,
                    "Duration of the one tilt per view [s]")
        ->capture_default_str();
    cmd->add_option("--tilt-range", options.tilt_half_range_deg, "Tilt sweeps +-this many degrees")
        ->capture_default_str();
    cmd->add_option(
           "--lidar", lidar,
           "LIDAR kind: tilt (the rig's tilting Hokuyo, ring = scan), spinning16 / spinning32 / "
           "spinning64 (VLP-16 / 32-beam / OS1-64 like, ring = beam), dense (Livox-like "
           "non-repetitive rosette, no ring field)")
        ->capture_default_str();
    cmd->add_option(
           "--range-noise", options.range_noise_m,
           "LIDAR range noise sigma [m]; < 0: the kind's own (tilt, spinning 0.01 m; dense 0.02 m) "
           "times --noise")
        ->capture_default_str();
    cmd->add_option("--dense-duration", options.dense_duration_s,
                    "Accumulation time of a dense cloud [s] at 100k points/s")
        ->capture_default_str();
    cmd->add_flag("--night", night, "Night temperatures and lighting");
    cmd->add_flag("--no-mixed-pixels", no_mixed,
                  "Disable the LIDAR beam footprint (mixed pixels at depth edges)");
  }
  void run(std::chrono::steady_clock::time_point t0) {
    options.time_of_day = night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
    options.rig.lidar.mixed_pixels = !no_mixed;
    options.lidar = rgbdt::sim::lidar_kind_from_string(lidar);
    const auto r = rgbdt::sim::write_calibration_session(out, options);
    std::printf(
        "calibration session: %d views, %d hole(s) of radius %.3f m, %s LIDAR -> %s (%.1f s)\n",
        static_cast<int>(r.views.size()), options.holes, r.target.radius_m, lidar.c_str(),
        r.directory.c_str(), seconds_since(t0));
  }
};

/// `rgbdt_sim checkerboard`: the paper's checkerboard for intrinsic calibration.
struct CheckerboardCommand {
  rgbdt::sim::CheckerboardSessionOptions options;
  std::string out;
  bool night = false;
  CLI::App* cmd = nullptr;

  void add_to(CLI::App& app) {
    cmd = app.add_subcommand("checkerboard",
                             "The paper's melamine checkerboard (2-inch squares; in the sun the "
                             "black squares are warmer, so the "
                             "pattern shows in thermal) at varied poses for intrinsic calibration: "
                             "<camera>/NNN.png, the true "
                             "intrinsics (<camera>.yaml, true_calib/) and ground_truth.yaml with "
                             "each view's T_camera_board and "
                             "true inner-corner pixels (row-major from the board's top-left).");
    cmd->add_option("--out", out, "Output folder (created)")->required();
    cmd->add_option("--camera", options.camera, "rgb or thermal")->capture_default_str();
    cmd->add_option("--views", options.views, "Number of images; 0 = 40 for thermal, 20 for rgb")
        ->capture_default_str();
    cmd->add_option("--seed", options.seed, "Random seed")->capture_default_str();
    cmd->add_option("--noise", options.noise_scale,
                    "Noise multiplier (NETD 0.05 K, fixed pattern, read noise)")
        ->capture_default_str();
    cmd->add_option("--squares-x", options.squares_x, "Squares across")->capture_default_str();
    cmd->add_option("--squares-y", options.squares_y, "Squares down")->capture_default_str();
    cmd->add_option("--square", options.square_m, "Square side [m]")->capture_default_str();
    cmd->add_option("--supersampling", options.supersampling, "N x N sub-samples per edge pixel")
        ->capture_default_str();
    cmd->add_flag("--night", night, "Night: little thermal contrast between the squares");
  }
  void run(std::chrono::steady_clock::time_point t0) {
    options.time_of_day = night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
    const auto r = rgbdt::sim::write_checkerboard_session(out, options);
    std::printf("checkerboard session: %d %s views of %dx%d inner corners -> %s (%.1f s)\n",
                static_cast<int>(r.views.size()), options.camera.c_str(), options.squares_x - 1,
                options.squares_y - 1, r.directory.c_str(), seconds_since(t0));
  }
};

/// `rgbdt_sim mapping`: the rig on a cart down a street.
struct MappingCommand {
  rgbdt::sim::MappingSessionOptions options;
  std::string out;
  bool night = false, no_images = false;
  CLI::App* cmd = nullptr;

  void add_to(CLI::App& app) {
    cmd = app.add_subcommand("mapping",
                             "The rig on a cart (~1 m/s, smooth weave) down a street of buildings, "
                             "trees and parked cars: the raw "
                             "LIDAR stream (lidar.rawlog: scans + encoder samples, MRPT format), "
                             "tilt_rig.yaml, one assembled cloud "
                             "per tilt (clouds/index.csv), RGB and thermal frames with index CSVs, "
                             "session.yaml, ground_truth.yaml "
                             "and ground_truth/trajectory.csv (T_world_lidar).");
    cmd->add_option("--out", out, "Output folder (created)")->required();
    cmd->add_option("--duration", options.duration_s, "Seconds of driving")->capture_default_str();
    cmd->add_option("--seed", options.seed, "Random seed (scene layout and noise)")
        ->capture_default_str();
    cmd->add_option("--noise", options.noise_scale, "Noise multiplier")->capture_default_str();
    cmd->add_option("--rgb-fps", options.rig.rgb_fps, "RGB frames per second")
        ->capture_default_str();
    cmd->add_option("--thermal-fps", options.rig.thermal_fps, "Thermal frames per second")
        ->capture_default_str();
    cmd->add_option("--tilt-duration", options.rig.lidar.profile.tilt_duration_s,
                    "One tilt of the LIDAR [s]")
        ->capture_default_str();
    cmd->add_option("--speed", options.trajectory.speed_m_s, "Cart speed [m/s]")
        ->capture_default_str();
    cmd->add_option("--weave-amplitude", options.trajectory.weave_amplitude_m,
                    "Sideways amplitude of the cart's weave [m]")
        ->capture_default_str();
    cmd->add_option("--weave-period", options.trajectory.weave_period_s,
                    "Period of the cart's weave [s] (shorter: sharper turns)")
        ->capture_default_str();
    cmd->add_option("--supersampling", options.supersampling, "N x N sub-samples per edge pixel")
        ->capture_default_str();
    cmd->add_flag("--night", night,
                  "Night: cool sky, warm walls, pavement that kept the day's heat");
    cmd->add_flag("--no-images", no_images, "LIDAR and trajectory only (fast)");
    cmd->add_option("--imu-rate", options.imu.rate_hz,
                    "IMU samples per second in imu.csv (a MEMS IMU in the LIDAR's axes: gyro "
                    "0.014 deg/s/sqrt(Hz) and a 0.2 deg/s bias, accelerometer 175 ug/sqrt(Hz), "
                    "times --noise); 0: no IMU")
        ->capture_default_str();
  }
  void run(std::chrono::steady_clock::time_point t0) {
    options.time_of_day = night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
    options.write_images = !no_images;
    const auto r = rgbdt::sim::write_mapping_session(out, options);
    std::printf(
        "mapping session: %.1f s, %d scans, %d encoder samples, %d clouds, %d rgb and %d thermal "
        "frames "
        "-> %s (%.1f s)\n",
        options.duration_s, r.scans, r.encoder_samples, r.clouds, r.rgb_frames, r.thermal_frames,
        r.directory.c_str(), seconds_since(t0));
  }
};

/// `rgbdt_sim coloring-setup`: paper Sec. 4.4's card at five depths.
struct ColoringCommand {
  rgbdt::sim::ColoringSetupOptions options;
  std::string out;
  CLI::App* cmd = nullptr;

  void add_to(CLI::App& app) {
    cmd = app.add_subcommand("coloring-setup",
                             "Paper Sec. 4.4: a white card before a wet black cloth at 5, 7.5, 10, "
                             "12 and 15 m, one view (cloud + "
                             "RGB + thermal) per depth, written as a mapping session with "
                             "clouds/index.csv and frame indexes at the "
                             "same times; ground_truth.yaml gives the card's corners per view.");
    cmd->add_option("--out", out, "Output folder (created)")->required();
    cmd->add_option("--depths", options.depths_m, "Card distances [m]")->capture_default_str();
    cmd->add_option("--seed", options.seed, "Random seed")->capture_default_str();
    cmd->add_option("--noise", options.noise_scale, "Noise multiplier")->capture_default_str();
    cmd->add_option("--supersampling", options.supersampling, "N x N sub-samples per edge pixel")
        ->capture_default_str();
  }
  void run(std::chrono::steady_clock::time_point t0) {
    const auto r = rgbdt::sim::write_coloring_setup(out, options);
    std::printf("coloring setup: %d depths -> %s (%.1f s)\n", r.clouds, r.directory.c_str(),
                seconds_since(t0));
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_sim: simulated RGB-Depth-Thermal rig sessions with ground truth.\n"
      "Every session folder gets ground_truth.yaml and true_calib/ beside the data.\n"
      "Run 'rgbdt_sim <command> --help' for the options of a command."};
  rgbdt::apps::add_config_option(app, argc, argv);
  app.require_subcommand(1);
  app.fallthrough();  // global flags may also follow the command
  bool quiet = false;
  app.add_flag("-q,--quiet", quiet, "Print only the summary");

  CalibrationCommand calibration;
  calibration.add_to(app);
  CheckerboardCommand checkerboard;
  checkerboard.add_to(app);
  MappingCommand mapping;
  mapping.add_to(app);
  ColoringCommand coloring;
  coloring.add_to(app);

  CLI11_PARSE(app, argc, argv);
  if (!quiet) rgbdt::core::set_log_sink(rgbdt::core::stderr_log_sink);

  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (*calibration.cmd) calibration.run(t0);
    if (*checkerboard.cmd) checkerboard.run(t0);
    if (*mapping.cmd) mapping.run(t0);
    if (*coloring.cmd) coloring.run(t0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_sim: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
