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

#include "app_config.hpp"
#include "detections_table.hpp"
#include "lidar_only.hpp"
#include "preflight.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/yaml_util.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/report.hpp"
#include "rgbdt/extrinsics/verdict.hpp"
#include "ros_outputs.hpp"
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

/// The text of an overlay's red banner: the estimate's first FAIL reason, or why this view
/// was rejected or named by the verdict; empty for a view in good standing.
std::string overlay_banner(const ext::CalibrationVerdict& verdict, size_t view) {
  if (verdict.failed() && !verdict.reasons.empty()) return verdict.reasons.front().text;
  return verdict.views[view].problem;
}

/// overlay_<camera>_<view>.jpg of an earlier run of `camera`, or .png of a run of a version
/// that wrote PNG overlays (the digits after the camera's name keep camera "rgb" from
/// matching camera "rgb_2"'s overlays).
bool is_overlay_of(const std::string& file, const std::string& camera) {
  const std::string prefix = "overlay_" + camera + "_";
  const std::size_t suffix_size = 4;  // ".jpg", ".png"
  if (file.size() <= prefix.size() + suffix_size || file.compare(0, prefix.size(), prefix) != 0) return false;
  const std::string suffix = file.substr(file.size() - suffix_size);
  if (suffix != rgbdt::calibrate::kOverlayExtension && suffix != ".png") return false;
  for (size_t k = prefix.size(); k < file.size() - suffix_size; ++k)
    if (!std::isdigit(static_cast<unsigned char>(file[k]))) return false;
  return true;
}

std::string overlay_name(const std::string& camera, int view) {
  std::string digits = std::to_string(view);
  if (digits.size() < 3) digits.insert(0, 3 - digits.size(), '0');
  return "overlay_" + camera + "_" + digits + rgbdt::calibrate::kOverlayExtension;
}

/// One row per hole of every view of a camera: the LIDAR hole, its image ellipse (when the
/// detectors paired the holes) and the view's residual and use at the estimate.
std::vector<rgbdt::calibrate::DetectionRow> detection_rows(const rgbdt::calibrate::CameraViews& cv,
                                                           const ext::EdgeAlignmentResult* r) {
  std::vector<rgbdt::calibrate::DetectionRow> rows;
  for (size_t k = 0; k < cv.views.size(); ++k) {
    const auto& lidar = cv.lidar_detections[k];
    for (size_t h = 0; h < lidar.holes.size(); ++h) {
      rgbdt::calibrate::DetectionRow row;
      row.view = cv.session_index[k];
      row.hole = static_cast<int>(h);
      row.lidar_center = lidar.holes[h].center;
      row.lidar_radius_m = lidar.holes[h].radius_m;
      row.radius_measured = lidar.holes[h].radius_measured;
      row.lidar_method = lidar.edge_method;
      if (h < cv.views[k].image_ellipses.size()) row.image_ellipse = cv.views[k].image_ellipses[h];
      if (r) {
        row.view_rms_px = r->views[k].rms_px;
        row.used = r->views[k].used;
      }
      rows.push_back(row);
    }
  }
  return rows;
}

constexpr char kDescription[] =
    "Calibrates the extrinsics between the LIDAR and the cameras of a calibration session by\n"
    "aligning the edges of the circle target in the LIDAR clouds with its edges in the images\n"
    "(paper Sec. 3.6, Eq. (2)). Targets are found automatically; seeds in session.yaml are "
    "hints\n"
    "(a seeded detection that fails falls back to the automatic one, and the report says so).\n"
    "No initial guess is needed. Every file the session names is checked first; all problems\n"
    "are listed at once (exit 1). Each camera is calibrated independently and judged:\n"
    "  PASS  every check within its threshold;\n"
    "  WARN  usable, with a caution: one view, a weakly constrained direction (named, with the\n"
    "        view to add), marginal residuals, views rejected or influential;\n"
    "  FAIL  not usable: the solver did not converge, |t| > --max-translation, the board behind\n"
    "        the camera, residual RMS or hole-centre reprojection > 5x the edge noise expected\n"
    "        at the views' depths, or views that disagree (leaving one out moves the estimate\n"
    "        by > 2 deg or 10 cm).\n"
    "Outputs in OUT_DIR:\n"
    "  extrinsics_<camera>.yaml           T_camera_lidar with covariance (PASS or WARN only)\n"
    "  extrinsics_<camera>.rejected.yaml  the estimate of a FAIL, for diagnosis only (never\n"
    "                                     used for anything else)\n"
    "  extrinsics_thermal_rgb.yaml        when both rgb and thermal pass or warn\n"
    "  static_transforms.launch.py        ROS 2 launch file: one tf2_ros "
    "static_transform_publisher\n"
    "                                     per PASS/WARN camera, T_lidar_camera (the inverse of "
    "the\n"
    "                                     YAML's), parent = the LIDAR frame, child = the "
    "camera's\n"
    "  urdf_joints.xml                    the same as URDF: one fixed <joint> per PASS/WARN "
    "camera\n"
    "                                     (origin xyz rpy = T_lidar_camera); both only when a\n"
    "                                     camera passed or warned. Frames: lidar and the "
    "camera's\n"
    "                                     name, as in the YAML, or as --frames renames them\n"
    "  overlay_<camera>_<view>.jpg        image edges blue, LIDAR circle before red, after\n"
    "                                     green; a red 'REJECTED: reason' banner on failed "
    "views\n"
    "  detections_<camera>.csv            one row per hole and view: LIDAR centre x y z [m],\n"
    "                                     LIDAR radius [m] and whether measured, image ellipse\n"
    "                                     centre u v, axes and angle [px, deg], the LIDAR\n"
    "                                     detector's method, the view's residual RMS and use\n"
    "  report.md                          last: verdict with its reasons and numbers per "
    "camera,\n"
    "                                     estimate, covariance, per-view residuals, errors "
    "against\n"
    "                                     ground_truth.yaml if the session has one.\n"
    "--lidar-only detects the target in every cloud, no camera needed (camera files may be\n"
    "absent), and writes detections_lidar.csv (camera columns empty) and report.md; exit 0\n"
    "when the target was found in every view, 2 when it was missed in some.\n"
    "Example: rgbdt_calibrate calib --out result --frames "
    "lidar=velodyne,rgb=camera_optical_frame\n"
    "Exit codes: 0 every camera PASS or WARN; 1 bad input; 2 a camera FAILed or was not\n"
    "calibrated (named in report.md and on stderr); 130 interrupted (no report.md).";

/// The command line of rgbdt_calibrate.
struct Arguments {
  std::string session_dir, out_dir, camera_choice = "all", method_name = "edge", initial_path;
  bool verbose = false;
  std::string seeds = "all";
  double max_translation_m = ext::VerdictOptions{}.max_translation_m;
  bool lidar_only = false;
  std::string frames_text;

  bool lidar_seeds() const { return seeds == "all" || seeds == "lidar"; }
  bool image_seeds() const { return seeds == "all" || seeds == "images"; }
};

void add_options(CLI::App& app, Arguments& args) {
  app.add_option("SESSION_DIR", args.session_dir, "calibration session folder (with session.yaml)")
      ->required();
  app.add_option("--out", args.out_dir, "output folder (created)")->required();
  app.add_option("--camera", args.camera_choice,
                 "camera to calibrate: a camera name of the session or 'all'")
      ->capture_default_str();
  app.add_option("--method", args.method_name,
                 "edge: smooth exact field, exact derivatives, robust (ours); paper: the paper's "
                 "10x10 plane-fit LUT with numeric differences")
      ->check(CLI::IsMember({"edge", "paper"}))
      ->capture_default_str();
  app.add_option("--initial", args.initial_path,
                 "optional initial T_camera_lidar (extrinsics YAML); used for the camera named by "
                 "its parent_frame, or for the only calibrated camera");
  app.add_option("--seeds", args.seeds,
                 "which seeds of session.yaml to try first: all, images, lidar or none (none: the "
                 "automatic detection everywhere). A seeded detection that fails falls back to "
                 "the automatic one")
      ->check(CLI::IsMember({"all", "images", "lidar", "none"}))
      ->capture_default_str();
  app.add_option(
         "--max-translation", args.max_translation_m,
         "largest plausible |t| of T_camera_lidar [m] (camera on the LIDAR's rig); beyond it "
         "the camera FAILs")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--frames", args.frames_text,
                 "frame ids of static_transforms.launch.py and urdf_joints.xml: lidar=FRAME and "
                 "CAMERA=FRAME, comma-separated, any subset, e.g. lidar=velodyne,rgb=camera_link "
                 "(default: the session's frames.yaml, which rgbdt_import writes from the bag's "
                 "frame_ids, else lidar and each camera's name; the extrinsics YAML keeps those)");
  app.add_flag(
      "--lidar-only", args.lidar_only,
      "detect the target in the clouds only: detections_lidar.csv and report.md, no camera");
  app.add_flag("-v,--verbose", args.verbose, "print library log messages (debug level)");
}

void create_output_folder(const std::string& out_dir) {
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir))
    throw core::Error(out_dir, "cannot create the output folder" +
                                   (ec ? " (" + ec.message() + ")" : std::string()));
}

/// Preflight: the intrinsics of the chosen cameras and every file the session names. Prints
/// all problems at once and returns false when there are any.
bool read_cameras(const core::CalibrationSession& session, const std::string& camera_choice,
                  std::map<std::string, core::PinholeCamera>* cameras) {
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
  for (const std::string& p : rgbdt::calibrate::preflight_problems(session, intrinsics))
    problems.push_back(p);
  if (!problems.empty()) {
    std::fprintf(stderr,
                 "error: session %s: %zu problem(s) with its files; nothing was calibrated:\n",
                 session.directory.c_str(), problems.size());
    for (const auto& p : problems) std::fprintf(stderr, "  %s\n", p.c_str());
    return false;
  }
  for (const auto& [name, in] : intrinsics) cameras->emplace(name, core::PinholeCamera(in));
  return true;
}

/// The frames of the ROS outputs: the session's frames.yaml (the bag's frame_ids, written by
/// rgbdt_import) when it has one, then --frames over it.
rgbdt::calibrate::RosFrames ros_frames_of(const core::CalibrationSession& session,
                                          const std::string& frames_text) {
  std::vector<std::string> camera_names;
  for (const auto& [name, entry] : session.cameras) camera_names.push_back(name);
  rgbdt::calibrate::RosFrames base;
  const fs::path file = fs::path(session.directory) / rgbdt::calibrate::kSessionFramesFile;
  if (fs::exists(file)) base = rgbdt::calibrate::read_session_frames(file.string(), camera_names);
  return rgbdt::calibrate::parse_ros_frames(frames_text, camera_names, std::move(base));
}

/// The files of this run in the output folder.
struct OutputPaths {
  fs::path out;
  std::string report, launch, urdf;
};

/// The output folder, cleared of this run's outputs from an earlier run: report.md first
/// (it marks a complete run), then what this run may write.
OutputPaths clear_output_folder(const std::string& out_dir,
                                const std::map<std::string, core::PinholeCamera>& cameras) {
  create_output_folder(out_dir);
  OutputPaths paths;
  paths.out = fs::path(out_dir);
  const fs::path& out = paths.out;
  paths.report = (out / "report.md").string();
  core::remove_stale_output(paths.report);
  paths.launch = (out / "static_transforms.launch.py").string();
  paths.urdf = (out / "urdf_joints.xml").string();
  core::remove_stale_output(paths.launch);
  core::remove_stale_output(paths.urdf);
  for (const auto& [name, camera] : cameras) {
    core::remove_stale_output((out / ("extrinsics_" + name + ".yaml")).string());
    core::remove_stale_output((out / ("extrinsics_" + name + ".rejected.yaml")).string());
    core::remove_stale_output((out / ("detections_" + name + ".csv")).string());
    for (const auto& e : fs::directory_iterator(out))
      if (is_overlay_of(e.path().filename().string(), name))
        core::remove_stale_output(e.path().string());
  }
  if (cameras.count("rgb") || cameras.count("thermal"))
    core::remove_stale_output((out / "extrinsics_thermal_rgb.yaml").string());
  return paths;
}

rgbdt::calibrate::SessionDetections detect_views(
    const core::CalibrationSession& session,
    const std::map<std::string, core::PinholeCamera>& cameras, const Arguments& args) {
  std::printf("session %s: %zu views, cameras:", session.directory.c_str(), session.views.size());
  for (const auto& [name, c] : cameras) std::printf(" %s", name.c_str());
  std::printf("\ndetecting the target...\n");
  return rgbdt::calibrate::detect_session_views(
      session, cameras, args.lidar_seeds(), args.image_seeds(),
      [](const std::string& line) {
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
      },
      [] { return core::interrupted(); });
}

/// "<what>; complete: <the extrinsics written>" on stderr, for an interrupted run.
void print_interrupted(const std::string& what, const std::vector<std::string>& written,
                       const char* why) {
  std::fprintf(stderr, "%s; complete:", what.c_str());
  for (const auto& w : written) std::fprintf(stderr, " %s", w.c_str());
  std::fprintf(stderr, "%s (%s)\n", written.empty() ? " nothing" : "", why);
}

/// What every camera's calibration shares.
struct Setup {
  std::size_t session_views = 0;
  std::size_t camera_count = 0;
  fs::path out;
  std::map<std::string, Eigen::Isometry3d> truth;  ///< T_camera_lidar of ground_truth.yaml
  std::optional<core::Extrinsics> initial;         ///< --initial
  ext::EdgeAlignmentOptions options;
  ext::VerdictOptions verdict_options;
};

Setup make_setup(const core::CalibrationSession& session, std::size_t camera_count,
                 const fs::path& out, const std::optional<core::Extrinsics>& initial,
                 const Arguments& args) {
  Setup setup;
  setup.session_views = session.views.size();
  setup.camera_count = camera_count;
  setup.out = out;
  setup.truth = read_ground_truth(session.directory);
  setup.initial = initial;
  setup.options.method = ext::edge_alignment_method_from_string(args.method_name);
  setup.verdict_options.max_translation_m = args.max_translation_m;
  setup.verdict_options.alignment = setup.options;
  return setup;
}

/// What the cameras' calibrations add up to.
struct Outcome {
  std::ostringstream report;                                ///< the sections of report.md
  std::map<std::string, ext::EdgeAlignmentResult> results;  ///< the cameras that passed or warned
  std::map<std::string, std::string> failed;                ///< camera -> reason
  std::vector<std::string> written;                         ///< their extrinsics YAMLs
};

/// The seeds that did not lead to the target and the views without a detection.
void list_views(std::ostream& os, const rgbdt::calibrate::CameraViews& cv) {
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
}

/// Camera `name` not calibrated: the reason on stderr and its FAILED section in the report,
/// with the verdict and the rejected estimate when there are any.
void fail(Outcome& outcome, const std::string& name, const rgbdt::calibrate::CameraViews& cv,
          const std::string& reason, const ext::EdgeAlignmentResult* r,
          const ext::CalibrationVerdict* verdict = nullptr,
          const std::optional<Eigen::Isometry3d>& truth_of_camera = {}) {
  outcome.failed[name] = reason;
  std::fprintf(stderr, "error: camera %s: not calibrated: %s\n", name.c_str(), reason.c_str());
  for (const auto& s : cv.skipped) std::fprintf(stderr, "  %s\n", s.c_str());
  std::ostringstream& report = outcome.report;
  report << "## " << name << "\n\n**FAILED: not calibrated: " << reason << ".** "
         << (verdict ? "Only extrinsics_" + name + ".rejected.yaml was written, for diagnosis."
                     : "Nothing was written for " + name + ".")
         << "\n\n";
  if (verdict) report << ext::format_verdict_report(*verdict);
  if (r && !cv.lidar_detections.empty())
    report << "Detections:\n\n"
           << rgbdt::calibrate::format_detections_markdown(detection_rows(cv, r));
  if (r)
    report << "The rejected estimate, for diagnosis only:\n\n"
           << ext::format_alignment_report(name, *r, truth_of_camera).substr(name.size() + 5);
  list_views(report, cv);
}

/// The alignment's estimate, outlier views and (with ground truth) error on stdout.
void print_alignment(const std::string& name, const ext::EdgeAlignmentResult& r,
                     const std::optional<Eigen::Isometry3d>& truth_of_camera) {
  std::printf("  %s: %s\n  RMS %.3f px, %d iterations, %.3f s, %s\n", name.c_str(),
              format_transform(r.T_camera_lidar).c_str(), r.rms_px, r.iterations, r.solve_time_s,
              r.converged ? "converged" : "NOT converged");
  for (int k : r.outlier_views())
    std::printf("  rejected %s: %s\n", r.views[k].name.c_str(), r.views[k].reason.c_str());
  if (truth_of_camera) {
    const ext::PoseError e = ext::pose_error(r.T_camera_lidar, *truth_of_camera);
    std::printf("  error vs ground truth: %.4f deg, %.3f cm\n", e.rotation_deg, e.translation_cm);
  }
}

/// detections_<camera>.csv, the overlays and, last, the extrinsics YAML (it exists only when
/// everything of this camera was written; .rejected.yaml for a FAIL). Returns its path.
std::string write_camera_outputs(const Setup& setup, const std::string& name,
                                 const core::PinholeCamera& camera,
                                 const rgbdt::calibrate::CameraViews& cv,
                                 const ext::EdgeAlignmentResult& r,
                                 const ext::CalibrationVerdict& verdict,
                                 const std::vector<rgbdt::calibrate::DetectionRow>& rows) {
  const fs::path& out = setup.out;
  const std::string csv_path = (out / ("detections_" + name + ".csv")).string();
  core::write_file_atomic(csv_path, rgbdt::calibrate::format_detections_csv(rows));
  std::printf("  wrote %s\n", csv_path.c_str());
  for (size_t k = 0; k < cv.views.size(); ++k) {
    const cv::Mat image = k < cv.images.size() && !cv.images[k].empty()
                              ? cv.images[k]
                              : cv::imread(cv.image_paths[k], cv::IMREAD_UNCHANGED);
    if (image.empty())
      throw core::Error(cv.image_paths[k], "cannot read the image for the overlay");
    core::TempOutput overlay((out / overlay_name(name, cv.session_index[k])).string());
    const cv::Mat drawn = ext::draw_overlay(image, cv.views[k], camera, r.T_camera_lidar_initial,
                                            r.T_camera_lidar, overlay_banner(verdict, k));
    if (!cv::imwrite(overlay.temp_path(), drawn, rgbdt::calibrate::kOverlayJpegParams))
      throw core::Error(overlay.path(), "cannot write the overlay JPEG");
    overlay.commit();
  }
  std::printf("  wrote %zu overlays\n", cv.views.size());
  core::Extrinsics e;
  e.parent_frame = name;
  e.child_frame = "lidar";
  e.T_parent_child = r.T_camera_lidar;
  if (r.covariance_valid) e.covariance = r.covariance;
  const std::string yaml_path =
      (out / ("extrinsics_" + name + (verdict.failed() ? ".rejected.yaml" : ".yaml"))).string();
  const std::string header =
      verdict.failed()
          ? "# REJECTED by rgbdt_calibrate's verdict, for diagnosis only: " + verdict.summary() +
                "\n"
          : std::string();
  core::write_file_atomic(yaml_path, header + core::format_extrinsics(e));
  std::printf("  wrote %s\n", yaml_path.c_str());
  return yaml_path;
}

/// One camera calibrated from its views and judged: its outputs written, its section (or
/// its failure) added to the outcome.
void calibrate_camera(const Setup& setup, const std::string& name,
                      const core::PinholeCamera& camera, const rgbdt::calibrate::CameraViews& cv,
                      Outcome& outcome) {
  for (const auto& s : cv.seed_notes) std::printf("  %s\n", s.c_str());
  if (cv.views.empty()) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the target was never found (LIDAR in %d of %zu views, %s image in %d)",
                  cv.lidar_found, setup.session_views, name.c_str(), cv.image_found);
    fail(outcome, name, cv, buf, nullptr);
    return;
  }
  std::optional<Eigen::Isometry3d> guess;
  if (setup.initial && (setup.initial->parent_frame == name || setup.camera_count == 1))
    guess = setup.initial->T_parent_child;
  std::printf("calibrating %s from %zu views (%s)...\n", name.c_str(), cv.views.size(),
              guess ? "given initial guess" : "closed-form initial guess");
  std::fflush(stdout);
  ext::EdgeAlignmentResult r;
  // The covariance takes each hole's LIDAR uncertainty from its detection.
  ext::EdgeAlignmentOptions camera_options = setup.options;
  camera_options.covariance_model.per_view = cv.hole_sigmas;
  ext::VerdictOptions camera_verdict_options = setup.verdict_options;
  camera_verdict_options.alignment = camera_options;
  try {
    r = ext::align_edges(cv.views, camera, camera_options, guess);
  } catch (const std::exception& e) {
    fail(outcome, name, cv, std::string("the alignment failed: ") + e.what(), nullptr);
    return;
  }
  std::optional<Eigen::Isometry3d> t;
  if (const auto it = setup.truth.find(name); it != setup.truth.end()) t = it->second;
  print_alignment(name, r, t);
  const ext::CalibrationVerdict verdict =
      ext::judge_calibration(cv.views, camera, r, camera_verdict_options);
  std::printf("  verdict: %s\n", ext::to_string(verdict.level).c_str());
  for (const auto& reason : verdict.reasons)
    std::printf("    %s: %s\n", ext::to_string(reason.level).c_str(), reason.text.c_str());
  const auto rows = detection_rows(cv, &r);
  try {
    const std::string yaml_path = write_camera_outputs(setup, name, camera, cv, r, verdict, rows);
    if (!verdict.failed()) outcome.written.push_back(yaml_path);
  } catch (const std::exception& e) {
    fail(outcome, name, cv, std::string("cannot write its outputs: ") + e.what(), nullptr);
    return;
  }
  if (verdict.failed()) {
    fail(outcome, name, cv, "verdict " + verdict.summary(), &r, &verdict, t);
    return;
  }
  outcome.results[name] = r;
  const std::string section = ext::format_alignment_report(name, r, t);
  const size_t heading_end = section.find("\n\n") + 2;  // the verdict right under "## <camera>"
  outcome.report << section.substr(0, heading_end) << ext::format_verdict_report(verdict)
                 << section.substr(heading_end) << "Detections:\n\n"
                 << rgbdt::calibrate::format_detections_markdown(rows);
  list_views(outcome.report, cv);
}

/// Every camera calibrated in turn; false when interrupted before one (said on stderr).
bool calibrate_cameras(const Setup& setup,
                       const std::map<std::string, core::PinholeCamera>& cameras,
                       const rgbdt::calibrate::SessionDetections& detections, Outcome& outcome) {
  for (const auto& [name, camera] : cameras) {
    if (core::interrupted()) {
      print_interrupted("interrupted before calibrating " + name, outcome.written,
                        "no report.md: the run is not complete");
      return false;
    }
    calibrate_camera(setup, name, camera, detections.cameras.at(name), outcome);
  }
  return true;
}

/// RGB to thermal from the two calibrations, when both passed or warned.
void write_thermal_rgb(const Setup& setup, Outcome& outcome) {
  const auto& results = outcome.results;
  if (!(results.count("rgb") && results.count("thermal"))) return;
  const auto& rgb = results.at("rgb");
  const auto& th = results.at("thermal");
  const ext::CameraToCamera c =
      ext::camera_to_camera(rgb.T_camera_lidar, rgb.covariance, th.T_camera_lidar, th.covariance);
  core::Extrinsics e;
  e.parent_frame = "thermal";
  e.child_frame = "rgb";
  e.T_parent_child = c.T_b_a;
  if (rgb.covariance_valid && th.covariance_valid) e.covariance = c.covariance;
  const std::string path = (setup.out / "extrinsics_thermal_rgb.yaml").string();
  core::write_file_atomic(path, core::format_extrinsics(e));
  std::printf("T_thermal_rgb: %s\n  wrote %s\n", format_transform(c.T_b_a).c_str(), path.c_str());
  std::ostringstream& report = outcome.report;
  report << "## thermal <- rgb\n\nT_thermal_rgb = T_thermal_lidar * T_rgb_lidar^-1: "
         << format_transform(c.T_b_a) << "\n";
  const auto& truth = setup.truth;
  if (truth.count("rgb") && truth.count("thermal")) {
    const ext::PoseError pe =
        ext::pose_error(c.T_b_a, truth.at("thermal") * truth.at("rgb").inverse());
    report << "\nError vs ground truth: " << pe.rotation_deg << " deg, " << pe.translation_cm
           << " cm\n";
    std::printf("  error vs ground truth: %.4f deg, %.3f cm\n", pe.rotation_deg, pe.translation_cm);
  }
  report << "\n";
}

/// The calibrated cameras for ROS (before report.md, which marks the run complete).
void write_ros_outputs(const OutputPaths& paths, const rgbdt::calibrate::RosFrames& ros_frames,
                       Outcome& outcome) {
  if (outcome.results.empty()) return;
  std::vector<rgbdt::calibrate::RosCamera> ros_cameras;
  for (const auto& [name, r] : outcome.results) ros_cameras.push_back({name, r.T_camera_lidar});
  core::write_file_atomic(
      paths.launch, rgbdt::calibrate::format_static_transforms_launch(ros_cameras, ros_frames));
  core::write_file_atomic(paths.urdf,
                          rgbdt::calibrate::format_urdf_joints(ros_cameras, ros_frames));
  std::printf("wrote %s\nwrote %s\n", paths.launch.c_str(), paths.urdf.c_str());
  std::ostringstream& report = outcome.report;
  report << "## ROS\n\n`static_transforms.launch.py` and `urdf_joints.xml`: T_lidar_camera of";
  for (const auto& c : ros_cameras)
    report << " " << c.name << " (" << ros_frames.camera(c.name) << ")";
  report << ", parent frame " << ros_frames.lidar << ".\n\n";
}

/// report.md: the result over all cameras, their sections and the configuration of the run.
void write_report(const std::string& report_path, const CLI::App& app, const Arguments& args,
                  const core::CalibrationSession& session, std::size_t camera_count,
                  const Outcome& outcome) {
  std::ostringstream doc;
  doc << "# rgbdt_calibrate report\n\nSession: `" << session.directory
      << "`, method: " << args.method_name << ", " << session.views.size() << " views.\n\n";
  if (outcome.failed.empty()) {
    doc << "Result: every camera calibrated (";
  } else {
    doc << "Result: **FAILED for " << outcome.failed.size() << " of " << camera_count
        << " camera(s)**";
    for (const auto& [name, why] : outcome.failed) doc << "\n\n- **" << name << "**: " << why;
    doc << "\n\nCalibrated (";
  }
  bool first = true;
  for (const auto& [name, r] : outcome.results) {
    doc << (first ? "" : ", ") << name;
    first = false;
  }
  doc << (first ? "none" : "") << ").\n\n" << outcome.report.str();
  doc << "## Configuration\n\nThe options this run used (`--config` reads this block "
         "back):\n\n```yaml\n"
      << rgbdt::apps::effective_config_yaml(app) << "```\n";
  core::write_file_atomic(report_path, doc.str());
  std::printf("wrote %s\n", report_path.c_str());
}

/// The run after parsing the command line; returns the exit code.
int run(const CLI::App& app, const Arguments& args) {
  const core::CalibrationSession session = core::read_calibration_session(args.session_dir);
  if (args.lidar_only) {
    create_output_folder(args.out_dir);
    return rgbdt::calibrate::run_lidar_only(session, args.out_dir, args.lidar_seeds());
  }
  std::map<std::string, core::PinholeCamera> cameras;
  if (!read_cameras(session, args.camera_choice, &cameras)) return 1;
  const rgbdt::calibrate::RosFrames ros_frames = ros_frames_of(session, args.frames_text);
  std::optional<core::Extrinsics> initial;
  if (!args.initial_path.empty()) initial = core::read_extrinsics(args.initial_path);
  const OutputPaths paths = clear_output_folder(args.out_dir, cameras);

  const auto detections = detect_views(session, cameras, args);
  if (detections.stopped) {
    std::fprintf(stderr,
                 "interrupted after %zu of %zu views of the detection; nothing was written "
                 "(no report.md)\n",
                 detections.views_done, session.views.size());
    return 130;
  }
  const Setup setup = make_setup(session, cameras.size(), paths.out, initial, args);
  Outcome outcome;
  if (!calibrate_cameras(setup, cameras, detections, outcome)) return 130;
  write_thermal_rgb(setup, outcome);
  if (core::interrupted()) {
    print_interrupted("interrupted before writing report.md", outcome.written,
                      "the run is not complete");
    return 130;
  }
  write_ros_outputs(paths, ros_frames, outcome);
  write_report(paths.report, app, args, session, cameras.size(), outcome);
  if (!outcome.failed.empty()) {
    std::fprintf(stderr, "error: %zu of %zu camera(s) not calibrated:", outcome.failed.size(),
                 cameras.size());
    for (const auto& [name, why] : outcome.failed) std::fprintf(stderr, " %s", name.c_str());
    std::fprintf(stderr, " (see %s)\n", paths.report.c_str());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{kDescription};
  rgbdt::apps::add_config_option(app, argc, argv);
  Arguments args;
  add_options(app, args);
  CLI11_PARSE(app, argc, argv);

  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(args.verbose ? core::LogLevel::kDebug : core::LogLevel::kWarning);
  core::install_interrupt_handler();
  try {
    return run(app, args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
