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

  // calibration
  rgbdt::sim::CalibrationSessionOptions cal;
  std::string cal_out;
  bool cal_night = false, cal_no_mixed = false;
  std::string cal_lidar = "tilt";
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
  calibration->add_option("--lidar", cal_lidar,
                          "LIDAR kind: tilt (the rig's tilting Hokuyo, ring = scan), spinning16 / spinning32 / "
                          "spinning64 (VLP-16 / 32-beam / OS1-64 like, ring = beam), dense (Livox-like "
                          "non-repetitive rosette, no ring field)")
      ->capture_default_str();
  calibration->add_option("--range-noise", cal.range_noise_m,
                          "LIDAR range noise sigma [m]; < 0: the kind's own (tilt, spinning 0.01 m; dense 0.02 m) "
                          "times --noise")
      ->capture_default_str();
  calibration->add_option("--dense-duration", cal.dense_duration_s,
                          "Accumulation time of a dense cloud [s] at 100k points/s")
      ->capture_default_str();
  calibration->add_flag("--night", cal_night, "Night temperatures and lighting");
  calibration->add_flag("--no-mixed-pixels", cal_no_mixed,
                        "Disable the LIDAR beam footprint (mixed pixels at depth edges)");

  // checkerboard
  rgbdt::sim::CheckerboardSessionOptions chk;
  std::string chk_out;
  bool chk_night = false;
  auto* checkerboard = app.add_subcommand(
      "checkerboard",
      "The paper's melamine checkerboard (2-inch squares; in the sun the black squares are warmer, so the "
      "pattern shows in thermal) at varied poses for intrinsic calibration: <camera>/NNN.png, the true "
      "intrinsics (<camera>.yaml, true_calib/) and ground_truth.yaml with each view's T_camera_board and "
      "true inner-corner pixels (row-major from the board's top-left).");
  checkerboard->add_option("--out", chk_out, "Output folder (created)")->required();
  checkerboard->add_option("--camera", chk.camera, "rgb or thermal")->capture_default_str();
  checkerboard->add_option("--views", chk.views, "Number of images; 0 = 40 for thermal, 20 for rgb")
      ->capture_default_str();
  checkerboard->add_option("--seed", chk.seed, "Random seed")->capture_default_str();
  checkerboard->add_option("--noise", chk.noise_scale, "Noise multiplier (NETD 0.05 K, fixed pattern, read noise)")
      ->capture_default_str();
  checkerboard->add_option("--squares-x", chk.squares_x, "Squares across")->capture_default_str();
  checkerboard->add_option("--squares-y", chk.squares_y, "Squares down")->capture_default_str();
  checkerboard->add_option("--square", chk.square_m, "Square side [m]")->capture_default_str();
  checkerboard->add_option("--supersampling", chk.supersampling, "N x N sub-samples per edge pixel")
      ->capture_default_str();
  checkerboard->add_flag("--night", chk_night, "Night: little thermal contrast between the squares");

  // mapping
  rgbdt::sim::MappingSessionOptions map;
  std::string map_out;
  bool map_night = false, map_no_images = false;
  auto* mapping = app.add_subcommand(
      "mapping",
      "The rig on a cart (~1 m/s, smooth weave) down a street of buildings, trees and parked cars: the raw "
      "LIDAR stream (lidar.rawlog: scans + encoder samples, MRPT format), tilt_rig.yaml, one assembled cloud "
      "per tilt (clouds/index.csv), RGB and thermal frames with index CSVs, session.yaml, ground_truth.yaml "
      "and ground_truth/trajectory.csv (T_world_lidar).");
  mapping->add_option("--out", map_out, "Output folder (created)")->required();
  mapping->add_option("--duration", map.duration_s, "Seconds of driving")->capture_default_str();
  mapping->add_option("--seed", map.seed, "Random seed (scene layout and noise)")->capture_default_str();
  mapping->add_option("--noise", map.noise_scale, "Noise multiplier")->capture_default_str();
  mapping->add_option("--rgb-fps", map.rig.rgb_fps, "RGB frames per second")->capture_default_str();
  mapping->add_option("--thermal-fps", map.rig.thermal_fps, "Thermal frames per second")->capture_default_str();
  mapping->add_option("--tilt-duration", map.rig.lidar.profile.tilt_duration_s, "One tilt of the LIDAR [s]")
      ->capture_default_str();
  mapping->add_option("--speed", map.trajectory.speed_m_s, "Cart speed [m/s]")->capture_default_str();
  mapping->add_option("--supersampling", map.supersampling, "N x N sub-samples per edge pixel")->capture_default_str();
  mapping->add_flag("--night", map_night, "Night: cool sky, warm walls, pavement that kept the day's heat");
  mapping->add_flag("--no-images", map_no_images, "LIDAR and trajectory only (fast)");

  // coloring-setup
  rgbdt::sim::ColoringSetupOptions col;
  std::string col_out;
  auto* coloring = app.add_subcommand(
      "coloring-setup",
      "Paper Sec. 4.4: a white card before a wet black cloth at 5, 7.5, 10, 12 and 15 m, one view (cloud + "
      "RGB + thermal) per depth, written as a mapping session with clouds/index.csv and frame indexes at the "
      "same times; ground_truth.yaml gives the card's corners per view.");
  coloring->add_option("--out", col_out, "Output folder (created)")->required();
  coloring->add_option("--depths", col.depths_m, "Card distances [m]")->capture_default_str();
  coloring->add_option("--seed", col.seed, "Random seed")->capture_default_str();
  coloring->add_option("--noise", col.noise_scale, "Noise multiplier")->capture_default_str();
  coloring->add_option("--supersampling", col.supersampling, "N x N sub-samples per edge pixel")->capture_default_str();

  CLI11_PARSE(app, argc, argv);
  if (!quiet) rgbdt::core::set_log_sink(rgbdt::core::stderr_log_sink);

  const auto t0 = std::chrono::steady_clock::now();
  try {
    if (*calibration) {
      cal.time_of_day = cal_night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
      cal.rig.lidar.mixed_pixels = !cal_no_mixed;
      cal.lidar = rgbdt::sim::lidar_kind_from_string(cal_lidar);
      const auto r = rgbdt::sim::write_calibration_session(cal_out, cal);
      std::printf("calibration session: %d views, %d hole(s) of radius %.3f m, %s LIDAR -> %s (%.1f s)\n",
                  static_cast<int>(r.views.size()), cal.holes, r.target.radius_m, cal_lidar.c_str(), r.directory.c_str(),
                  seconds_since(t0));
    }
    if (*checkerboard) {
      chk.time_of_day = chk_night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
      const auto r = rgbdt::sim::write_checkerboard_session(chk_out, chk);
      std::printf("checkerboard session: %d %s views of %dx%d inner corners -> %s (%.1f s)\n",
                  static_cast<int>(r.views.size()), chk.camera.c_str(), chk.squares_x - 1, chk.squares_y - 1,
                  r.directory.c_str(), seconds_since(t0));
    }
    if (*mapping) {
      map.time_of_day = map_night ? rgbdt::sim::TimeOfDay::kNight : rgbdt::sim::TimeOfDay::kDay;
      map.write_images = !map_no_images;
      const auto r = rgbdt::sim::write_mapping_session(map_out, map);
      std::printf("mapping session: %.1f s, %d scans, %d encoder samples, %d clouds, %d rgb and %d thermal frames "
                  "-> %s (%.1f s)\n",
                  map.duration_s, r.scans, r.encoder_samples, r.clouds, r.rgb_frames, r.thermal_frames,
                  r.directory.c_str(), seconds_since(t0));
    }
    if (*coloring) {
      const auto r = rgbdt::sim::write_coloring_setup(col_out, col);
      std::printf("coloring setup: %d depths -> %s (%.1f s)\n", r.clouds, r.directory.c_str(), seconds_since(t0));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_sim: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
