// rgbdt_sim: writes simulated sessions (calibration, checkerboard, mapping, coloring
// setup) with their ground truth, in the formats of design.md and contracts.md.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <exception>
#include <string>

#include "rgbdt/core/log.hpp"
#include "rgbdt/sim/calibration_session.hpp"

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_sim: simulated RGB-Depth-Thermal rig sessions with ground truth.\n"
      "Every session folder gets ground_truth.yaml and true_calib/ beside the data.\n"
      "Run 'rgbdt_sim <command> --help' for the options of a command."};
  app.require_subcommand(1);
  app.fallthrough();  // global flags may also follow the command
  bool quiet = false;
  app.add_flag("-q,--quiet", quiet, "Print only the summary");

  // calibration
  rgbdt::sim::CalibrationSessionOptions cal;
  std::string cal_out;
  bool cal_night = false, cal_no_mixed = false;
  auto* calibration = app.add_subcommand(
      "calibration",
      "Circle-hole target (white board, 1 or 4 holes) in front of a wet black cloth at varied poses 3-8 m: "
      "one assembled LIDAR tilt (clouds/NNN.pcd), one RGB (rgb/NNN.png) and one thermal image "
      "(thermal/NNN.png, 16-bit counts) per view, session.yaml, ground_truth.yaml, true_calib/.");
  calibration->add_option("--out", cal_out, "Output folder (created)")->required();
  calibration->add_option("--views", cal.views, "Number of target placements")->capture_default_str();
  calibration->add_option("--seed", cal.seed, "Random seed (same seed, same session)")->capture_default_str();
  calibration->add_option("--noise", cal.noise_scale,
                          "Noise multiplier for LIDAR range sigma (0.01 m), image noise and NETD (0.05 K)")
      ->capture_default_str();
  calibration->add_option("--holes", cal.holes, "Holes in the target: 1 (r 0.30 m) or 4 (2x2, r 0.12 m)")
      ->capture_default_str();
  calibration->add_option("--radius", cal.hole_radius_m, "Hole radius [m]; 0 = default for --holes")
      ->capture_default_str();
  calibration->add_option("--min-distance", cal.min_distance_m, "Nearest board distance [m]")->capture_default_str();
  calibration->add_option("--max-distance", cal.max_distance_m, "Farthest board distance [m]")->capture_default_str();
  calibration->add_option("--supersampling", cal.supersampling, "N x N sub-samples per edge pixel")
      ->capture_default_str();
  calibration->add_option("--tilt-duration", cal.tilt_duration_s, "Duration of the one tilt per view [s]")
      ->capture_default_str();
  calibration->add_option("--tilt-range", cal.tilt_half_range_deg, "Tilt sweeps +-this many degrees")
      ->capture_default_str();
  calibration->add_flag("--night", cal_night, "Night temperatures and lighting");
  calibration->add_flag("--no-mixed-pixels", cal_no_mixed, "Disable LIDAR mixed pixels at depth edges");

  CLI11_PARSE(app, argc, argv);
  if (!quiet) rgbdt::core::set_log_sink(rgbdt::core::stderr_log_sink);

  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (*calibration) {
      cal.time_of_day = cal_night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
      cal.rig.lidar.mixed_pixels = !cal_no_mixed;
      const auto r = rgbdt::sim::write_calibration_session(cal_out, cal);
      std::printf("calibration session: %d views, %d hole(s) of radius %.3f m -> %s (%.1f s)\n",
                  static_cast<int>(r.views.size()), cal.holes, r.target.radius_m, r.directory.c_str(),
                  seconds_since(t0));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_sim: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
