// rgbdt_calibrate: camera-LIDAR extrinsics from a calibration session (paper Sec. 3.6).
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/yaml_util.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/report.hpp"
#include "preflight.hpp"
#include "session_views.hpp"

namespace fs = std::filesystem;
namespace core = rgbdt::core;
namespace ext = rgbdt::extrinsics;

namespace {

/// T_camera_lidar of each camera in ground_truth.yaml (simulated sessions), if present.
std::map<std::string, Eigen::Isometry3d> read_ground_truth(const std::string& session_dir) {
  std::map<std::string, Eigen::Isometry3d> out;
  const fs::path path = fs::path(session_dir) / "ground_truth.yaml";
  if (!fs::exists(path)) return out;
  const core::YamlField root(core::load_yaml_file(path.string()), path.string());
  const std::optional<core::YamlField> extrinsics = root.find("extrinsics");
  if (!extrinsics) return out;
  for (const auto& [name, entry] : extrinsics->entries("a mapping of camera name to extrinsics")) {
    YAML::Emitter em;
    em << entry.node();
    const core::Extrinsics e = core::parse_extrinsics(em.c_str(), path.string() + ": extrinsics." + name);
    out[name] = e.T_parent_child;
  }
  return out;
}

std::string format_transform(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d rpy = core::rotation_to_rpy(T.linear()) * 180.0 / M_PI;
  char buf[160];
  std::snprintf(buf, sizeof buf, "t = [%.4f %.4f %.4f] m, rpy = [%.3f %.3f %.3f] deg",
                T.translation().x(), T.translation().y(), T.translation().z(), rpy.x(), rpy.y(), rpy.z());
  return buf;
}

/// A camera on the LIDAR's rig: an estimate that puts it further away than this is wrong.
constexpr double kMaxLeverArmM = 5.0;

/// Why an estimate must not be used, or an empty string when it passes every check.
std::string verdict_problem(const ext::EdgeAlignmentResult& r) {
  if (!r.T_camera_lidar.matrix().allFinite() || !std::isfinite(r.rms_px))
    return "the estimate is not finite";
  if (!r.converged) return "the solver did not converge (" + r.message + ")";
  int used = 0;
  for (const auto& v : r.views) used += v.used ? 1 : 0;
  if (used == 0) return "every view was rejected as an outlier";
  const double lever = r.T_camera_lidar.translation().norm();
  if (lever > kMaxLeverArmM) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "translation of %.3f m, expected at most %.1f m for a camera on the LIDAR's rig",
                  lever, kMaxLeverArmM);
    return buf;
  }
  return {};
}

/// overlay_<camera>_<view>.png of an earlier run of `camera` (the digits after the camera's
/// name keep camera "rgb" from matching camera "rgb_2"'s overlays).
bool is_overlay_of(const std::string& file, const std::string& camera) {
  const std::string prefix = "overlay_" + camera + "_", suffix = ".png";
  if (file.size() <= prefix.size() + suffix.size() || file.compare(0, prefix.size(), prefix) != 0 ||
      file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0)
    return false;
  for (size_t k = prefix.size(); k < file.size() - suffix.size(); ++k)
    if (!std::isdigit(static_cast<unsigned char>(file[k]))) return false;
  return true;
}

std::string overlay_name(const std::string& camera, int view) {
  std::string digits = std::to_string(view);
  if (digits.size() < 3) digits.insert(0, 3 - digits.size(), '0');
  return "overlay_" + camera + "_" + digits + ".png";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Calibrates the extrinsics between the LIDAR and the cameras of a calibration session by\n"
      "aligning the edges of the circle target in the LIDAR clouds with its edges in the images\n"
      "(paper Sec. 3.6, Eq. (2)). Targets are found automatically; seeds in session.yaml are hints\n"
      "(a seeded detection that fails falls back to the automatic one, and the report says so).\n"
      "No initial guess is needed. Every file the session names is checked first; all problems\n"
      "are listed at once (exit 1). Each camera is calibrated independently: writes\n"
      "OUT_DIR/extrinsics_<camera>.yaml (T_camera_lidar with covariance) for each camera whose\n"
      "estimate passes its checks, extrinsics_thermal_rgb.yaml when both cameras are calibrated,\n"
      "overlay_<camera>_<view>.png (image edges blue, LIDAR circle before red, after green) and,\n"
      "last, report.md (estimate, covariance, per-view residuals, rejected views, failed cameras\n"
      "with the reason, errors against ground_truth.yaml if the session has one). Exit codes:\n"
      "0 all cameras calibrated; 1 bad input; 2 a camera failed (named in report.md and on\n"
      "stderr); 130 interrupted (no report.md)."};
  std::string session_dir, out_dir, camera_choice = "all", method_name = "edge", initial_path;
  bool verbose = false;
  std::string seeds = "all";
  app.add_option("SESSION_DIR", session_dir, "calibration session folder (with session.yaml)")->required();
  app.add_option("--out", out_dir, "output folder (created)")->required();
  app.add_option("--camera", camera_choice, "camera to calibrate: a camera name of the session or 'all'")
      ->capture_default_str();
  app.add_option("--method", method_name,
                 "edge: smooth exact field, exact derivatives, robust (ours); paper: the paper's "
                 "10x10 plane-fit LUT with numeric differences")
      ->check(CLI::IsMember({"edge", "paper"}))
      ->capture_default_str();
  app.add_option("--initial", initial_path,
                 "optional initial T_camera_lidar (extrinsics YAML); used for the camera named by "
                 "its parent_frame, or for the only calibrated camera");
  app.add_option("--seeds", seeds,
                 "which seeds of session.yaml to try first: all, images, lidar or none (none: the "
                 "automatic detection everywhere). A seeded detection that fails falls back to "
                 "the automatic one")
      ->check(CLI::IsMember({"all", "images", "lidar", "none"}))
      ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "print library log messages (debug level)");
  CLI11_PARSE(app, argc, argv);

  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(verbose ? core::LogLevel::kDebug : core::LogLevel::kWarning);
  core::install_interrupt_handler();
  try {
    const core::CalibrationSession session = core::read_calibration_session(session_dir);
    // Preflight: every camera_info and every file the session names, all problems at once.
    std::vector<std::string> problems;
    std::map<std::string, core::CameraIntrinsics> intrinsics;
    bool any_camera = false;
    for (const auto& [name, entry] : session.cameras) {
      if (camera_choice != "all" && camera_choice != name) continue;
      any_camera = true;
      try {
        intrinsics.emplace(name, core::read_camera_info(entry.intrinsics));
      } catch (const std::exception& e) {
        problems.push_back(std::string(e.what()) + " (intrinsics of camera " + name + ")");
      }
    }
    if (!any_camera) {
      std::string names;
      for (const auto& [name, entry] : session.cameras) names += " " + name;
      throw core::Error(session.directory + "/session.yaml",
                        "no camera '" + camera_choice + "' (the session has:" + names + ")");
    }
    for (const std::string& p : rgbdt::calibrate::preflight_problems(session, intrinsics)) problems.push_back(p);
    if (!problems.empty()) {
      std::fprintf(stderr, "error: session %s: %zu problem(s) with its files; nothing was calibrated:\n",
                   session.directory.c_str(), problems.size());
      for (const auto& p : problems) std::fprintf(stderr, "  %s\n", p.c_str());
      return 1;
    }
    std::map<std::string, core::PinholeCamera> cameras;
    for (const auto& [name, in] : intrinsics) cameras.emplace(name, core::PinholeCamera(in));
    std::optional<core::Extrinsics> initial;
    if (!initial_path.empty()) initial = core::read_extrinsics(initial_path);

    // The output folder, cleared of this run's outputs from an earlier run: report.md first
    // (it marks a complete run), then what this run may write.
    {
      std::error_code ec;
      fs::create_directories(out_dir, ec);
      if (ec || !fs::is_directory(out_dir))
        throw core::Error(out_dir, "cannot create the output folder" + (ec ? " (" + ec.message() + ")" : std::string()));
    }
    const fs::path out = fs::path(out_dir);
    const std::string report_path = (out / "report.md").string();
    core::remove_stale_output(report_path);
    for (const auto& [name, camera] : cameras) {
      core::remove_stale_output((out / ("extrinsics_" + name + ".yaml")).string());
      for (const auto& e : fs::directory_iterator(out))
        if (is_overlay_of(e.path().filename().string(), name)) core::remove_stale_output(e.path().string());
    }
    if (cameras.count("rgb") || cameras.count("thermal"))
      core::remove_stale_output((out / "extrinsics_thermal_rgb.yaml").string());

    std::printf("session %s: %zu views, cameras:", session.directory.c_str(), session.views.size());
    for (const auto& [name, c] : cameras) std::printf(" %s", name.c_str());
    std::printf("\ndetecting the target...\n");
    const auto detections = rgbdt::calibrate::detect_session_views(
        session, cameras, seeds == "all" || seeds == "lidar", seeds == "all" || seeds == "images",
        [](const std::string& line) {
          std::printf("%s\n", line.c_str());
          std::fflush(stdout);
        },
        [] { return core::interrupted(); });
    if (detections.stopped) {
      std::fprintf(stderr,
                   "interrupted after %zu of %zu views of the detection; nothing was written "
                   "(no report.md)\n",
                   detections.views_done, session.views.size());
      return 130;
    }
    const auto& per_camera = detections.cameras;

    const auto truth = read_ground_truth(session.directory);
    ext::EdgeAlignmentOptions options;
    options.method = ext::edge_alignment_method_from_string(method_name);
    std::ostringstream report;
    std::map<std::string, ext::EdgeAlignmentResult> results;
    std::map<std::string, std::string> failed;  // camera -> reason
    std::vector<std::string> written;
    for (const auto& [name, camera] : cameras) {
      if (core::interrupted()) {
        std::fprintf(stderr, "interrupted before calibrating %s; complete:", name.c_str());
        for (const auto& w : written) std::fprintf(stderr, " %s", w.c_str());
        std::fprintf(stderr, "%s (no report.md: the run is not complete)\n", written.empty() ? " nothing" : "");
        return 130;
      }
      const auto& cv = per_camera.at(name);
      const auto list_views = [&](std::ostream& os) {
        if (!cv.seed_notes.empty()) {
          os << "Seeds that did not lead to the target:\n\n";
          for (const auto& s : cv.seed_notes) os << "- " << s << "\n";
          os << "\n";
        }
        if (!cv.skipped.empty()) {
          os << "Views without a detection:\n\n";
          for (const auto& s : cv.skipped) os << "- " << s << "\n";
          os << "\n";
        }
      };
      const auto fail = [&](const std::string& reason, const ext::EdgeAlignmentResult* r) {
        failed[name] = reason;
        std::fprintf(stderr, "error: camera %s: not calibrated: %s\n", name.c_str(), reason.c_str());
        for (const auto& s : cv.skipped) std::fprintf(stderr, "  %s\n", s.c_str());
        report << "## " << name << "\n\n**FAILED: not calibrated: " << reason << ".** Nothing was written for "
               << name << ".\n\n";
        if (r) report << "The rejected estimate, for diagnosis only:\n\n" << ext::format_alignment_report(name, *r);
        list_views(report);
      };
      for (const auto& s : cv.seed_notes) std::printf("  %s\n", s.c_str());
      if (cv.views.empty()) {
        char buf[200];
        std::snprintf(buf, sizeof buf, "the target was never found (LIDAR in %d of %zu views, %s image in %d)",
                      cv.lidar_found, session.views.size(), name.c_str(), cv.image_found);
        fail(buf, nullptr);
        continue;
      }
      std::optional<Eigen::Isometry3d> guess;
      if (initial && (initial->parent_frame == name || cameras.size() == 1)) guess = initial->T_parent_child;
      std::printf("calibrating %s from %zu views (%s)...\n", name.c_str(), cv.views.size(),
                  guess ? "given initial guess" : "closed-form initial guess");
      std::fflush(stdout);
      ext::EdgeAlignmentResult r;
      try {
        r = ext::align_edges(cv.views, camera, options, guess);
      } catch (const std::exception& e) {
        fail(std::string("the alignment failed: ") + e.what(), nullptr);
        continue;
      }
      std::printf("  %s: %s\n  RMS %.3f px, %d iterations, %.3f s, %s\n", name.c_str(),
                  format_transform(r.T_camera_lidar).c_str(), r.rms_px, r.iterations, r.solve_time_s,
                  r.converged ? "converged" : "NOT converged");
      for (int k : r.outlier_views())
        std::printf("  rejected %s: %s\n", r.views[k].name.c_str(), r.views[k].reason.c_str());
      std::optional<Eigen::Isometry3d> t;
      if (const auto it = truth.find(name); it != truth.end()) {
        t = it->second;
        const ext::PoseError e = ext::pose_error(r.T_camera_lidar, *t);
        std::printf("  error vs ground truth: %.4f deg, %.3f cm\n", e.rotation_deg, e.translation_cm);
      }
      if (const std::string why = verdict_problem(r); !why.empty()) {
        fail(why, &r);
        continue;
      }
      try {
        // Overlays first, the extrinsics last: extrinsics_<camera>.yaml exists only when
        // everything of this camera was written.
        for (size_t k = 0; k < cv.views.size(); ++k) {
          const cv::Mat image = cv::imread(cv.image_paths[k], cv::IMREAD_UNCHANGED);
          if (image.empty()) throw core::Error(cv.image_paths[k], "cannot read the image for the overlay");
          core::TempOutput overlay((out / overlay_name(name, cv.session_index[k])).string());
          if (!cv::imwrite(overlay.temp_path(), ext::draw_overlay(image, cv.views[k], camera, r.T_camera_lidar_initial,
                                                                  r.T_camera_lidar),
                           rgbdt::calibrate::kOverlayPngParams))
            throw core::Error(overlay.path(), "cannot write the overlay PNG");
          overlay.commit();
        }
        std::printf("  wrote %zu overlays\n", cv.views.size());
        core::Extrinsics e;
        e.parent_frame = name;
        e.child_frame = "lidar";
        e.T_parent_child = r.T_camera_lidar;
        if (r.covariance_valid) e.covariance = r.covariance;
        const std::string yaml_path = (out / ("extrinsics_" + name + ".yaml")).string();
        core::write_file_atomic(yaml_path, core::format_extrinsics(e));
        std::printf("  wrote %s\n", yaml_path.c_str());
        written.push_back(yaml_path);
      } catch (const std::exception& e) {
        fail(std::string("cannot write its outputs: ") + e.what(), nullptr);
        continue;
      }
      results[name] = r;
      report << ext::format_alignment_report(name, r, t);
      list_views(report);
    }
    // RGB to thermal from the two calibrations.
    if (results.count("rgb") && results.count("thermal")) {
      const auto& rgb = results.at("rgb");
      const auto& th = results.at("thermal");
      const ext::CameraToCamera c = ext::camera_to_camera(rgb.T_camera_lidar, rgb.covariance,
                                                          th.T_camera_lidar, th.covariance);
      core::Extrinsics e;
      e.parent_frame = "thermal";
      e.child_frame = "rgb";
      e.T_parent_child = c.T_b_a;
      if (rgb.covariance_valid && th.covariance_valid) e.covariance = c.covariance;
      const std::string path = (out / "extrinsics_thermal_rgb.yaml").string();
      core::write_file_atomic(path, core::format_extrinsics(e));
      std::printf("T_thermal_rgb: %s\n  wrote %s\n", format_transform(c.T_b_a).c_str(), path.c_str());
      report << "## thermal <- rgb\n\nT_thermal_rgb = T_thermal_lidar * T_rgb_lidar^-1: "
             << format_transform(c.T_b_a) << "\n";
      if (truth.count("rgb") && truth.count("thermal")) {
        const ext::PoseError pe =
            ext::pose_error(c.T_b_a, truth.at("thermal") * truth.at("rgb").inverse());
        report << "\nError vs ground truth: " << pe.rotation_deg << " deg, " << pe.translation_cm << " cm\n";
        std::printf("  error vs ground truth: %.4f deg, %.3f cm\n", pe.rotation_deg, pe.translation_cm);
      }
      report << "\n";
    }
    if (core::interrupted()) {
      std::fprintf(stderr, "interrupted before writing report.md; complete:");
      for (const auto& w : written) std::fprintf(stderr, " %s", w.c_str());
      std::fprintf(stderr, "%s (the run is not complete)\n", written.empty() ? " nothing" : "");
      return 130;
    }
    std::ostringstream doc;
    doc << "# rgbdt_calibrate report\n\nSession: `" << session.directory << "`, method: " << method_name << ", "
        << session.views.size() << " views.\n\n";
    if (failed.empty()) {
      doc << "Result: every camera calibrated (";
    } else {
      doc << "Result: **FAILED for " << failed.size() << " of " << cameras.size() << " camera(s)**";
      for (const auto& [name, why] : failed) doc << "\n\n- **" << name << "**: " << why;
      doc << "\n\nCalibrated (";
    }
    bool first = true;
    for (const auto& [name, r] : results) {
      doc << (first ? "" : ", ") << name;
      first = false;
    }
    doc << (first ? "none" : "") << ").\n\n" << report.str();
    core::write_file_atomic(report_path, doc.str());
    std::printf("wrote %s\n", report_path.c_str());
    if (!failed.empty()) {
      std::fprintf(stderr, "error: %zu of %zu camera(s) not calibrated:", failed.size(), cameras.size());
      for (const auto& [name, why] : failed) std::fprintf(stderr, " %s", name.c_str());
      std::fprintf(stderr, " (see %s)\n", report_path.c_str());
      return 2;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
