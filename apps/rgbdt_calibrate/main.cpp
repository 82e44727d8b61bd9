// rgbdt_calibrate: camera-LIDAR extrinsics from a calibration session (paper Sec. 3.6).
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
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
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/report.hpp"
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
  const YAML::Node root = YAML::LoadFile(path.string());
  if (!root["extrinsics"]) return out;
  for (const auto& entry : root["extrinsics"]) {
    YAML::Emitter em;
    em << entry.second;
    const core::Extrinsics e = core::parse_extrinsics(em.c_str(), path.string() + ": extrinsics." +
                                                                      entry.first.as<std::string>());
    out[entry.first.as<std::string>()] = e.T_parent_child;
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Calibrates the extrinsics between the LIDAR and the cameras of a calibration session by\n"
      "aligning the edges of the circle target in the LIDAR clouds with its edges in the images\n"
      "(paper Sec. 3.6, Eq. (2)). Targets are found automatically unless session.yaml gives seeds;\n"
      "no initial guess is needed. Writes OUT_DIR/extrinsics_<camera>.yaml (T_camera_lidar with\n"
      "covariance), extrinsics_thermal_rgb.yaml when both cameras are calibrated, report.md\n"
      "(estimate, covariance, per-view residuals, rejected views, errors against\n"
      "ground_truth.yaml if the session has one) and overlay_<camera>_<view>.png (image edges\n"
      "blue, LIDAR circle before red, after green). Exits non-zero when the target is never found."};
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
                 "which seeds of session.yaml to use: all, images, lidar or none (none: find the "
                 "targets automatically everywhere)")
      ->check(CLI::IsMember({"all", "images", "lidar", "none"}))
      ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "print library log messages (debug level)");
  CLI11_PARSE(app, argc, argv);

  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(verbose ? core::LogLevel::kDebug : core::LogLevel::kWarning);
  try {
    const core::CalibrationSession session = core::read_calibration_session(session_dir);
    std::map<std::string, core::PinholeCamera> cameras;
    for (const auto& [name, entry] : session.cameras) {
      if (camera_choice != "all" && camera_choice != name) continue;
      cameras.emplace(name, core::PinholeCamera(core::read_camera_info(entry.intrinsics)));
    }
    if (cameras.empty()) {
      std::string names;
      for (const auto& [name, entry] : session.cameras) names += " " + name;
      throw core::Error(session.directory + "/session.yaml",
                        "no camera '" + camera_choice + "' (the session has:" + names + ")");
    }
    std::optional<core::Extrinsics> initial;
    if (!initial_path.empty()) initial = core::read_extrinsics(initial_path);
    fs::create_directories(out_dir);
    std::printf("session %s: %zu views, cameras:", session.directory.c_str(), session.views.size());
    for (const auto& [name, c] : cameras) std::printf(" %s", name.c_str());
    std::printf("\ndetecting the target...\n");
    const auto per_camera = rgbdt::calibrate::detect_session_views(
        session, cameras, seeds == "all" || seeds == "lidar", seeds == "all" || seeds == "images", [](const std::string& line) { std::printf("%s\n", line.c_str()); std::fflush(stdout); });

    const auto truth = read_ground_truth(session.directory);
    ext::EdgeAlignmentOptions options;
    options.method = ext::edge_alignment_method_from_string(method_name);
    std::ostringstream report;
    report << "# rgbdt_calibrate report\n\nSession: `" << session.directory << "`, method: "
           << method_name << ", " << session.views.size() << " views.\n\n";
    std::map<std::string, ext::EdgeAlignmentResult> results;
    bool failed = false;
    for (const auto& [name, camera] : cameras) {
      const auto& cv = per_camera.at(name);
      if (cv.views.empty()) {
        std::fprintf(stderr,
                     "error: camera %s: the target was never found (LIDAR in %d of %zu views, %s "
                     "image in %d); nothing to calibrate\n",
                     name.c_str(), cv.lidar_found, session.views.size(), name.c_str(), cv.image_found);
        for (const auto& s : cv.skipped) std::fprintf(stderr, "  %s\n", s.c_str());
        report << "## " << name << "\n\n**Not calibrated: the target was never found.**\n\n";
        for (const auto& s : cv.skipped) report << "- " << s << "\n";
        report << "\n";
        failed = true;
        continue;
      }
      std::optional<Eigen::Isometry3d> guess;
      if (initial && (initial->parent_frame == name || cameras.size() == 1)) guess = initial->T_parent_child;
      std::printf("calibrating %s from %zu views (%s)...\n", name.c_str(), cv.views.size(),
                  guess ? "given initial guess" : "closed-form initial guess");
      const ext::EdgeAlignmentResult r = ext::align_edges(cv.views, camera, options, guess);
      results[name] = r;
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
      core::Extrinsics out;
      out.parent_frame = name;
      out.child_frame = "lidar";
      out.T_parent_child = r.T_camera_lidar;
      if (r.covariance_valid) out.covariance = r.covariance;
      const std::string yaml_path = (fs::path(out_dir) / ("extrinsics_" + name + ".yaml")).string();
      core::write_extrinsics(yaml_path, out);
      std::printf("  wrote %s\n", yaml_path.c_str());
      report << ext::format_alignment_report(name, r, t);
      if (!cv.skipped.empty()) {
        report << "Views without a detection:\n\n";
        for (const auto& s : cv.skipped) report << "- " << s << "\n";
        report << "\n";
      }
      for (size_t k = 0; k < cv.views.size(); ++k) {
        const cv::Mat image = cv::imread(cv.image_paths[k], cv::IMREAD_UNCHANGED);
        char file[64];
        std::snprintf(file, sizeof file, "overlay_%s_%03d.png", name.c_str(), cv.session_index[k]);
        const std::string path = (fs::path(out_dir) / file).string();
        if (!cv::imwrite(path, ext::draw_overlay(image, cv.views[k], camera, r.T_camera_lidar_initial,
                                                 r.T_camera_lidar)))
          throw core::Error(path, "cannot write the overlay PNG");
      }
      std::printf("  wrote %zu overlays\n", cv.views.size());
    }
    // RGB to thermal from the two calibrations.
    if (results.count("rgb") && results.count("thermal")) {
      const auto& rgb = results.at("rgb");
      const auto& th = results.at("thermal");
      const ext::CameraToCamera c = ext::camera_to_camera(rgb.T_camera_lidar, rgb.covariance,
                                                          th.T_camera_lidar, th.covariance);
      core::Extrinsics out;
      out.parent_frame = "thermal";
      out.child_frame = "rgb";
      out.T_parent_child = c.T_b_a;
      if (rgb.covariance_valid && th.covariance_valid) out.covariance = c.covariance;
      const std::string path = (fs::path(out_dir) / "extrinsics_thermal_rgb.yaml").string();
      core::write_extrinsics(path, out);
      std::printf("T_thermal_rgb: %s\n  wrote %s\n", format_transform(c.T_b_a).c_str(), path.c_str());
      report << "## thermal <- rgb\n\nT_thermal_rgb = T_thermal_lidar * T_rgb_lidar^-1: "
             << format_transform(c.T_b_a) << "\n";
      if (truth.count("rgb") && truth.count("thermal")) {
        const ext::PoseError e =
            ext::pose_error(c.T_b_a, truth.at("thermal") * truth.at("rgb").inverse());
        report << "\nError vs ground truth: " << e.rotation_deg << " deg, " << e.translation_cm << " cm\n";
        std::printf("  error vs ground truth: %.4f deg, %.3f cm\n", e.rotation_deg, e.translation_cm);
      }
      report << "\n";
    }
    const std::string report_path = (fs::path(out_dir) / "report.md").string();
    std::ofstream(report_path) << report.str();
    std::printf("wrote %s\n", report_path.c_str());
    return failed ? 2 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
