// rgbdt_coloring_error: how wrong is the colour of a LIDAR point, and why (paper Sec. 4.3-4.4).
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "app_config.hpp"
#include "report.hpp"
#include "setup.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/error_model/error_propagation.hpp"
#include "rgbdt/error_model/paper_analysis.hpp"

namespace fs = std::filesystem;
using namespace rgbdt;

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kMaxTableRows = 10000;
constexpr int kMaxMonteCarlo = 1000000;

struct Options {
  std::string config_yaml;  ///< the effective configuration, for the reports
  // Paper mode.
  double fx = 0.0, lidar_noise_m = 0.02, fx_error = 0.0, x_m = 5.0;
  bool json = false;
  // Report mode.
  std::string calib, intrinsics, report, camera, rig, setup;
  std::vector<double> intrinsics_sigma, rotation_sigma_deg, translation_sigma_m, pixel, what_if;
  double beam_sigma_deg = 0.0, tilt_sigma_deg = 0.025;
  double depth_min = 1.0, depth_max = 20.0, depth_step = 1.0;
  int monte_carlo = 0;
};

std::string number(double v, int decimals = 6) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// Every problem of the numeric options at once, each naming its option and value; empty
// when all are usable. Non-finite values would otherwise reach the model as NaN
// covariances, and an unbounded depth range would fill memory with table rows.
std::string option_problems(const Options& o) {
  std::ostringstream why;
  const auto check = [&](const char* option, double v, bool non_negative) {
    if (!std::isfinite(v)) {
      why << "\n  " << option << " " << v << ": expected a finite number";
    } else if (non_negative && v < 0.0) {
      why << "\n  " << option << " " << v << ": expected a standard deviation >= 0";
    }
  };
  const auto check_all = [&](const char* option, const std::vector<double>& values, bool non_negative) {
    for (double v : values) check(option, v, non_negative);
  };
  check("--fx", o.fx, false);
  check("--fx-error", o.fx_error, false);
  check("--x", o.x_m, false);
  check("--lidar-noise", o.lidar_noise_m, true);
  check("--beam-sigma-deg", o.beam_sigma_deg, true);
  check("--tilt-sigma-deg", o.tilt_sigma_deg, true);
  check_all("--intrinsics-sigma", o.intrinsics_sigma, true);
  check_all("--rotation-sigma-deg", o.rotation_sigma_deg, true);
  check_all("--translation-sigma-m", o.translation_sigma_m, true);
  check_all("--what-if-error", o.what_if, false);
  check_all("--pixel", o.pixel, false);
  if (!(std::isfinite(o.depth_min) && std::isfinite(o.depth_max) && std::isfinite(o.depth_step) && o.depth_min > 0.0 &&
        o.depth_max > o.depth_min && o.depth_step > 0.0)) {
    why << "\n  --depth-min " << o.depth_min << " --depth-max " << o.depth_max << " --depth-step " << o.depth_step
        << ": expected finite 0 < min < max and step > 0";
  } else if ((o.depth_max - o.depth_min) / o.depth_step > kMaxTableRows) {
    why << "\n  --depth-step " << o.depth_step << ": gives more than " << kMaxTableRows
        << " table rows between --depth-min and --depth-max";
  }
  if (o.monte_carlo < 0 || o.monte_carlo > kMaxMonteCarlo) {
    why << "\n  --monte-carlo " << o.monte_carlo << ": expected 0 (none) to " << kMaxMonteCarlo << " samples";
  }
  return why.str();
}

int run_paper(const Options& o, bool has_fx_error) {
  const double lidar_depth = error_model::lidar_noise_depth_m(o.fx, o.lidar_noise_m, o.x_m);
  if (o.json) {
    std::cout << "{\"fx_px\": " << number(o.fx) << ", \"lidar_noise_m\": " << number(o.lidar_noise_m)
              << ", \"x_m\": " << number(o.x_m) << ", \"lidar_noise_depth_m\": " << number(lidar_depth);
    if (has_fx_error) {
      std::cout << ", \"fx_error_px\": " << number(o.fx_error)
                << ", \"intrinsics_depth_m\": " << number(error_model::intrinsics_depth_m(o.fx, o.fx_error, o.lidar_noise_m, o.x_m))
                << ", \"printed_eq14_depth_m\": "
                << number(error_model::printed_eq14_depth_m(o.fx, o.fx_error, o.lidar_noise_m, o.x_m));
    }
    std::cout << "}\n";
    return 0;
  }
  std::cout << "fx = " << number(o.fx, 5) << " px, LIDAR noise = " << number(o.lidar_noise_m, 4) << " m, X = " << o.x_m
            << "\n"
            << "Eq. (9):  LIDAR noise moves a projection by < 1 px beyond Z = " << number(lidar_depth) << " m\n";
  if (has_fx_error) {
    std::cout << "Eq. (14): with dfx = " << o.fx_error << " px, beyond Z = "
              << number(error_model::intrinsics_depth_m(o.fx, o.fx_error, o.lidar_noise_m, o.x_m))
              << " m (Eq. (9) with fx + dfx, as the paper's numbers are computed;\n"
              << "          Eq. (14) as printed gives "
              << number(error_model::printed_eq14_depth_m(o.fx, o.fx_error, o.lidar_noise_m, o.x_m)) << " m)\n";
  }
  return 0;
}

/// The extrinsics file of a camera in a calibration folder: extrinsics_<camera>.yaml if a
/// camera is named, else the one whose parent_frame is the intrinsics' camera_name.
std::string find_extrinsics(const std::string& calib_dir, const std::string& camera, const std::string& camera_name) {
  if (!fs::is_directory(calib_dir)) throw core::Error(calib_dir, "--calib: expected a calibration folder");
  if (!camera.empty()) {
    const fs::path path = fs::path(calib_dir) / ("extrinsics_" + camera + ".yaml");
    if (!fs::exists(path)) throw core::Error(path.string(), "missing (named by --camera " + camera + ")");
    return path.string();
  }
  std::ostringstream found;
  for (const auto& entry : fs::directory_iterator(calib_dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("extrinsics_", 0) != 0 || entry.path().extension() != ".yaml") continue;
    const core::Extrinsics e = core::read_extrinsics(entry.path().string());
    if (e.parent_frame == camera_name) return entry.path().string();
    found << " " << name << " (parent_frame '" << e.parent_frame << "')";
  }
  const std::string list = found.str();
  throw core::Error(calib_dir, "no extrinsics_<camera>.yaml has parent_frame '" + camera_name + "' (found:" +
                                   (list.empty() ? std::string(" none") : list) + "); name the camera with --camera");
}

int run_report(const Options& o) {
  error_model::ErrorSources sources;
  sources.intrinsics = core::read_camera_info(o.intrinsics);
  const std::string extrinsics_path = find_extrinsics(o.calib, o.camera, sources.intrinsics.camera_name);
  // The camera of the file found is its parent_frame (the reader puts the camera first).
  const core::Extrinsics extrinsics = core::read_extrinsics(extrinsics_path, core::ExtrinsicsFrames{});
  sources.T_camera_lidar = extrinsics.T_parent_child;
  apps::ReportSettings settings;
  settings.camera_name = o.camera.empty() ? sources.intrinsics.camera_name : o.camera;
  settings.intrinsics_path = o.intrinsics;
  settings.extrinsics_path = extrinsics_path;
  settings.config_yaml = o.config_yaml;

  if (!o.rotation_sigma_deg.empty() || !o.translation_sigma_m.empty()) {
    if (o.rotation_sigma_deg.size() != 3 || o.translation_sigma_m.size() != 3) {
      throw std::invalid_argument("--rotation-sigma-deg and --translation-sigma-m: expected 3 values each");
    }
    core::Vector6d sigma;
    sigma << o.rotation_sigma_deg[0] * kDeg, o.rotation_sigma_deg[1] * kDeg, o.rotation_sigma_deg[2] * kDeg,
        o.translation_sigma_m[0], o.translation_sigma_m[1], o.translation_sigma_m[2];
    sources.extrinsics_covariance = sigma.cwiseAbs2().asDiagonal();
    settings.extrinsics_sigma_note = "from --rotation-sigma-deg / --translation-sigma-m (diagonal)";
  } else if (extrinsics.covariance) {
    sources.extrinsics_covariance = *extrinsics.covariance;
    settings.extrinsics_sigma_note = "the file's 6x6 `covariance` (rx ry rz tx ty tz of to_vector6)";
  } else {
    throw core::Error(extrinsics_path,
                      "no 'covariance' key (expected the 6x6 covariance rgbdt_calibrate writes); "
                      "or pass --rotation-sigma-deg RX RY RZ --translation-sigma-m TX TY TZ");
  }
  if (!o.intrinsics_sigma.empty()) {
    const Eigen::VectorXd sigma = Eigen::Map<const Eigen::VectorXd>(o.intrinsics_sigma.data(), o.intrinsics_sigma.size());
    sources.intrinsics_covariance = Eigen::MatrixXd(sigma.cwiseAbs2().asDiagonal());
    settings.intrinsics_sigma_note = "--intrinsics-sigma (diagonal)";
  } else {
    settings.intrinsics_sigma_note = "none given (pass --intrinsics-sigma FX FY CX CY [distortion...]): intrinsics curve is 0";
    std::cerr << "note: no --intrinsics-sigma; the intrinsics contribution is taken as zero\n";
  }
  sources.lidar.range_sigma_m = o.lidar_noise_m;
  sources.lidar.beam_angle_sigma_rad = o.beam_sigma_deg * kDeg;
  sources.lidar.tilt_angle_sigma_rad = o.tilt_sigma_deg * kDeg;
  if (!o.rig.empty()) sources.rig = core::read_tilt_rig(o.rig);

  if (!(o.depth_min > 0.0) || !(o.depth_max > o.depth_min) || !(o.depth_step > 0.0)) {
    throw std::invalid_argument("--depth-min/--depth-max/--depth-step: expected 0 < min < max and step > 0");
  }
  for (double d = o.depth_min; d <= o.depth_max + 1e-9; d += o.depth_step) settings.table_depths_m.push_back(d);
  settings.plot_min_m = o.depth_min;
  settings.plot_max_m = o.depth_max;
  if (!o.pixel.empty()) {
    if (o.pixel.size() != 2) throw std::invalid_argument("--pixel: expected two values U V");
    settings.pixel = Eigen::Vector2d(o.pixel[0], o.pixel[1]);
  } else {
    settings.pixel = Eigen::Vector2d(sources.intrinsics.cx, sources.intrinsics.cy);
  }
  settings.monte_carlo_samples = o.monte_carlo;

  const error_model::ColoringErrorModel model(sources);
  const apps::ReportFiles files = apps::write_report(o.report, model, settings);
  std::cout << "camera " << settings.camera_name << ", extrinsics " << extrinsics_path << "\n";
  for (double d : {5.0, 10.0, 15.0}) {
    if (d < o.depth_min || d > o.depth_max) continue;
    const auto p = model.predict(settings.pixel, d);
    std::cout << "  depth " << number(d, 1) << " m: total " << number(p[error_model::Source::kTotal].pixel_rms_px(), 2)
              << " px, " << number(100.0 * p[error_model::Source::kTotal].surface_rms_m(), 2) << " cm on the surface (x "
              << number(100.0 * p[error_model::Source::kTotal].surface_sigma_x_m(), 2) << ", y "
              << number(100.0 * p[error_model::Source::kTotal].surface_sigma_y_m(), 2) << ")\n";
  }
  std::cout << "wrote " << files.markdown << "\nwrote " << files.png << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_coloring_error: how wrong is the colour of a LIDAR point, and why (paper Sec. 4.3, 4.4).\n\n"
      "Modes:\n"
      "  paper   --fx F --lidar-noise M [--fx-error DF] [--x X] [--json]\n"
      "          the paper's closed-form depths: Eq. (9) (LIDAR noise stops moving a projection by\n"
      "          1 px) and, with --fx-error, Eq. (14) as the paper evaluates it (Eq. (9) with fx + dfx).\n"
      "          JSON keys: lidar_noise_depth_m, intrinsics_depth_m, printed_eq14_depth_m.\n"
      "  report  --calib DIR --intrinsics camera.yaml --report OUT_DIR\n"
      "          predicted colouring error vs depth (first-order propagation of LIDAR noise, intrinsics\n"
      "          and extrinsics covariance), per source, as OUT_DIR/coloring_error_<camera>.md + .png.\n"
      "          DIR holds extrinsics_<camera>.yaml (rgbdt_calibrate); the one whose parent_frame is the\n"
      "          intrinsics' camera_name is used, or extrinsics_<NAME>.yaml with --camera NAME.\n"
      "  setup   --setup SESSION --calib DIR [--camera NAME] [--report OUT_DIR] [--what-if-error ...]\n"
      "          the coloring-error setup of Sec. 4.4 (white card before a black cloth at several depths,\n"
      "          e.g. from 'rgbdt_sim coloring-setup'): colours each cloud with DIR's extrinsics, measures\n"
      "          the mis-coloured band along the card edges in x and y and prints Table 2 (RGB) / Table 3\n"
      "          (thermal) with the model's predicted band, the paper's figures and, when the session has\n"
      "          true_calib/, the band the calibration error should cause. --report also writes a PNG\n"
      "          per view with the mis-coloured points ringed; --rotation-sigma-deg/--translation-sigma-m\n"
      "          give the covariance when the extrinsics file has none.\n\n"
      "Examples:\n"
      "  rgbdt_coloring_error --fx 1335.054 --lidar-noise 0.02 --fx-error 2 --json\n"
      "  rgbdt_coloring_error --calib calib/ --intrinsics rgb.yaml --report out/ --intrinsics-sigma 2 2 1.5 1.5\n"
      "  rgbdt_coloring_error --setup coloring_session/ --calib calib/\n"};
  rgbdt::apps::add_config_option(app, argc, argv);
  Options o;
  auto* fx = app.add_option("--fx", o.fx, "paper mode: focal length fx [px]");
  auto* noise = app.add_option("--lidar-noise", o.lidar_noise_m, "LIDAR range noise dz [m], 1 sigma (default 0.02)");
  auto* fx_error = app.add_option("--fx-error", o.fx_error, "paper mode: error of fx, dfx [px] (Eq. (14))");
  app.add_option("--x", o.x_m, "paper mode: the lateral coordinate X of Eq. (9) (default 5, as in the paper)");
  app.add_flag("--json", o.json, "paper mode: print JSON");
  auto* calib = app.add_option("--calib", o.calib, "report mode: calibration folder with extrinsics_<camera>.yaml");
  auto* intrinsics = app.add_option("--intrinsics", o.intrinsics, "report mode: ROS camera_info YAML of the camera");
  auto* report = app.add_option("--report", o.report, "report/setup mode: output folder for the .md (and .png)");
  auto* setup = app.add_option("--setup", o.setup, "setup mode: session folder (or its session.yaml) of the Sec. 4.4 setup");
  app.add_option("--camera", o.camera, "camera name: use extrinsics_<NAME>.yaml");
  app.add_option("--intrinsics-sigma", o.intrinsics_sigma,
                 "std devs of fx fy cx cy [px] and optionally the distortion coefficients "
                 "(as calibrateCameraExtended reports them)")
      ->expected(4, 9);
  app.add_option("--rotation-sigma-deg", o.rotation_sigma_deg,
                 "std devs of rx ry rz [deg]; overrides the file's covariance (with --translation-sigma-m)")
      ->expected(3);
  app.add_option("--translation-sigma-m", o.translation_sigma_m, "std devs of tx ty tz [m]")->expected(3);
  app.add_option("--what-if-error", o.what_if,
                 "setup mode: colour with the calibration moved by RX RY RZ [deg] TX TY TZ [m] in the camera frame, "
                 "to see the band a calibration error of that size leaves")
      ->expected(6);
  app.add_option("--beam-sigma-deg", o.beam_sigma_deg, "LIDAR beam angle noise [deg] (default 0)");
  app.add_option("--tilt-sigma-deg", o.tilt_sigma_deg,
                 "tilt angle noise [deg] (default 0.025: a 4096-count encoder's quantisation)");
  app.add_option("--rig", o.rig, "tilt_rig.yaml for the LIDAR geometry (default: scanner on the tilt axis)");
  app.add_option("--pixel", o.pixel, "image position U V [px] (default: the principal point)")->expected(2);
  app.add_option("--depth-min", o.depth_min, "report depth range start [m] (default 1)");
  app.add_option("--depth-max", o.depth_max, "report depth range end [m] (default 20)");
  app.add_option("--depth-step", o.depth_step, "report table step [m] (default 1)");
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "print the libraries' debug messages");
  app.add_option("--monte-carlo", o.monte_carlo, "add a Monte Carlo check column with N samples per depth");
  CLI11_PARSE(app, argc, argv);
  (void)noise;
  o.config_yaml = rgbdt::apps::effective_config_yaml(app);

  core::set_log_sink(core::stderr_log_sink);
  if (verbose) core::set_log_level(core::LogLevel::kDebug);
  try {
    if (const std::string why = option_problems(o); !why.empty()) {
      throw std::invalid_argument("bad options, nothing was computed:" + why);
    }
    const bool paper = fx->count() > 0;
    const bool setup_mode = setup->count() > 0;
    const bool report_mode = !setup_mode && (calib->count() > 0 || intrinsics->count() > 0 || report->count() > 0);
    if (static_cast<int>(paper) + static_cast<int>(setup_mode) + static_cast<int>(report_mode) != 1) {
      std::cerr << "error: choose one mode: --fx (paper), --calib/--intrinsics/--report (report) or --setup; see --help\n";
      return 2;
    }
    if (paper) return run_paper(o, fx_error->count() > 0);
    if (setup_mode) {
      if (calib->count() == 0) {
        std::cerr << "error: --setup needs --calib DIR with extrinsics_<camera>.yaml; see --help\n";
        return 2;
      }
      apps::SetupSettings settings;
      settings.calib_dir = o.calib;
      settings.camera = o.camera;
      settings.intrinsics_sigma = o.intrinsics_sigma;
      settings.lidar_noise_m = o.lidar_noise_m;
      settings.report_dir = o.report;
      settings.config_yaml = o.config_yaml;
      if (!o.rotation_sigma_deg.empty() || !o.translation_sigma_m.empty()) {
        if (o.rotation_sigma_deg.size() != 3 || o.translation_sigma_m.size() != 3) {
          throw std::invalid_argument("--rotation-sigma-deg and --translation-sigma-m: expected 3 values each");
        }
        core::Vector6d sigma;
        sigma << o.rotation_sigma_deg[0] * kDeg, o.rotation_sigma_deg[1] * kDeg, o.rotation_sigma_deg[2] * kDeg,
            o.translation_sigma_m[0], o.translation_sigma_m[1], o.translation_sigma_m[2];
        settings.extrinsics_covariance = core::Matrix6d(sigma.cwiseAbs2().asDiagonal());
      }
      if (!o.what_if.empty()) {
        core::Vector6d offset;
        offset << o.what_if[0] * kDeg, o.what_if[1] * kDeg, o.what_if[2] * kDeg, o.what_if[3], o.what_if[4], o.what_if[5];
        settings.extrinsics_offset = offset;
      }
      return apps::run_setup(apps::read_setup_session(o.setup), settings);
    }
    if (calib->count() == 0 || intrinsics->count() == 0 || report->count() == 0) {
      std::cerr << "error: report mode needs --calib, --intrinsics and --report; see --help\n";
      return 2;
    }
    return run_report(o);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
