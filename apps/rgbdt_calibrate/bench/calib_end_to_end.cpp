// calib_end_to_end: the time of a whole camera-LIDAR calibration on a simulated session,
// stage by stage (load, LIDAR detection, image detection, solve, report, overlays), for our
// edge alignment and for the paper's (EdgeAlignmentMethod::kPaperPlaneFit), and the time of
// the rgbdt_calibrate app itself on the same session. Target: the app under 2 s on one core;
// the solve of ours at least 100x faster than the paper's.
//
//   cmake --build build --target calib_end_to_end rgbdt_calibrate
//   taskset -c 0 build/bin/calib_end_to_end [--session DIR] [--views 10] [--seed 1] [--repeats 3]
//                                           [--solve-repeats 20]
//
// Without --session the bench writes the simulator's session (rgbdt_sim calibration --views
// N --seed S) into a temporary folder. Times are wall time and process CPU time (all
// threads), the minimum over the repeats (the machine may be shared). The solve ratio is
// taken from each camera's solve repeated --solve-repeats times on the same views by both
// methods, interleaved (the fastest of each, CPU time of the thread): a solve of a few ms is
// otherwise at the mercy of one scheduler tick or a spell of load. Interleaved, each of our
// solves starts with the caches the paper's LUTs flushed; the same solves back to back (warm)
// are printed beside it. Exit 1 when a target is missed or a calibration fails.
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "../session_views.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/yaml_util.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/report.hpp"
#include "rgbdt/sim/calibration_session.hpp"

extern char** environ;

namespace fs = std::filesystem;
namespace ct = rgbdt::calib_targets;
namespace core = rgbdt::core;
namespace ext = rgbdt::extrinsics;

namespace {

enum Stage { kLoad, kLidar, kImage, kSolve, kReport, kOverlays, kNumStages };
const std::array<const char*, kNumStages> kStageNames = {"load (clouds, images)", "LIDAR detection",
                                                         "image detection", "solve",
                                                         "report", "overlays (draw, JPEG)"};

/// CPU time [s] of `clock`: CLOCK_PROCESS_CPUTIME_ID (all threads) or CLOCK_THREAD_CPUTIME_ID.
double cpu_s(clockid_t clock) {
  timespec ts;
  clock_gettime(clock, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
double thread_cpu_s() { return cpu_s(CLOCK_THREAD_CPUTIME_ID); }
double process_cpu_s() { return cpu_s(CLOCK_PROCESS_CPUTIME_ID); }

struct Time {
  double wall = 0.0, cpu = 0.0;
};

/// Accumulates wall and CPU time of a stage over the scopes that measure it.
class StageClock {
 public:
  explicit StageClock(Time* t) : t_(t), wall0_(std::chrono::steady_clock::now()), cpu0_(process_cpu_s()) {}
  ~StageClock() {
    t_->wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
    t_->cpu += process_cpu_s() - cpu0_;
  }

 private:
  Time* t_;
  std::chrono::steady_clock::time_point wall0_;
  double cpu0_;
};

struct RunResult {
  std::array<Time, kNumStages> stage{};
  int lidar_found = 0, image_found = 0, image_total = 0;
  std::map<std::string, ext::EdgeAlignmentResult> results;
  std::map<std::string, std::vector<ext::TargetView>> views;  ///< what each camera's solve read
  std::string problem;  ///< empty when every camera was calibrated
};

/// The steps of rgbdt_calibrate in-process (detections shared by both methods' runs are
/// done again: each run is a whole calibration).
RunResult run_pipeline(const core::CalibrationSession& session,
                       const std::map<std::string, core::PinholeCamera>& cameras,
                       ext::EdgeAlignmentMethod method, const fs::path& out_dir) {
  RunResult r;
  std::map<std::string, std::vector<ext::TargetView>> views;
  std::map<std::string, std::vector<std::string>> image_paths;
  for (std::size_t i = 0; i < session.views.size(); ++i) {
    const core::CalibrationView& view = session.views[i];
    rgbdt::cloud::LoadedCloud cloud;
    std::map<std::string, cv::Mat> images;
    {
      StageClock c(&r.stage[kLoad]);
      cloud = rgbdt::cloud::load_cloud(view.cloud);
      for (const auto& [name, camera] : cameras) images[name] = cv::imread(view.images.at(name), cv::IMREAD_UNCHANGED);
    }
    ct::LidarTargetDetection lidar;
    {
      StageClock c(&r.stage[kLidar]);
      lidar = ct::detect_target_in_cloud(*cloud.cloud, cloud.has_ring, session.target);
    }
    r.lidar_found += lidar.ok;
    for (const auto& [name, camera] : cameras) {
      ct::ImageTargetDetection det;
      {
        StageClock c(&r.stage[kImage]);
        det = ct::detect_target_in_image(images[name], session.target, camera);
      }
      ++r.image_total;
      r.image_found += det.ok;
      if (!lidar.ok || !det.ok) continue;
      views[name].push_back(rgbdt::calibrate::make_target_view(lidar, det, session.target, images[name].size(),
                                                                "view " + std::to_string(i)));
      image_paths[name].push_back(view.images.at(name));
    }
  }
  ext::EdgeAlignmentOptions options;
  options.method = method;
  for (const auto& [name, camera] : cameras) {
    if (views[name].empty()) {
      r.problem += name + ": no view with both detections; ";
      continue;
    }
    ext::EdgeAlignmentResult result;
    {
      StageClock c(&r.stage[kSolve]);
      result = ext::align_edges(views[name], camera, options);
    }
    {
      StageClock c(&r.stage[kReport]);
      const std::string md = ext::format_alignment_report(name, result);
      if (md.empty()) r.problem += name + ": empty report; ";
    }
    {
      StageClock c(&r.stage[kOverlays]);
      for (std::size_t k = 0; k < views[name].size(); ++k) {
        const cv::Mat image = cv::imread(image_paths[name][k], cv::IMREAD_UNCHANGED);
        const fs::path overlay =
            out_dir / ("overlay_" + name + "_" + std::to_string(k) + rgbdt::calibrate::kOverlayExtension);
        if (!cv::imwrite(overlay.string(),
                         ext::draw_overlay(image, views[name][k], camera, result.T_camera_lidar_initial,
                                           result.T_camera_lidar),
                         rgbdt::calibrate::kOverlayJpegParams))
          r.problem += overlay.string() + ": cannot write; ";
      }
    }
    if (!result.converged) r.problem += name + ": not converged; ";
    r.results[name] = result;
  }
  r.views = std::move(views);
  return r;
}

/// T_camera_lidar of each camera in the session's ground_truth.yaml (empty without one).
std::map<std::string, Eigen::Isometry3d> read_truth(const fs::path& session_dir) {
  std::map<std::string, Eigen::Isometry3d> out;
  const fs::path path = session_dir / "ground_truth.yaml";
  if (!fs::exists(path)) return out;
  const core::YamlField root(core::load_yaml_file(path.string()), path.string());
  const std::optional<core::YamlField> extrinsics = root.find("extrinsics");
  if (!extrinsics) return out;
  for (const auto& [name, entry] : extrinsics->entries("a mapping of camera name to extrinsics")) {
    YAML::Emitter em;
    em << entry.node();
    out[name] = core::parse_extrinsics(em.c_str(), path.string() + ": extrinsics." + name).T_parent_child;
  }
  return out;
}

/// Runs `argv` as a child process; its wall time and CPU time (user + system, from wait4).
Time time_child(const std::vector<std::string>& args, int* exit_code) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  Time t;
  if (posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) {
    posix_spawn_file_actions_destroy(&actions);
    *exit_code = -1;
    return t;
  }
  posix_spawn_file_actions_destroy(&actions);
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  t.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto sec = [](const timeval& tv) { return static_cast<double>(tv.tv_sec) + 1e-6 * static_cast<double>(tv.tv_usec); };
  t.cpu = sec(ru.ru_utime) + sec(ru.ru_stime);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return t;
}

Time total(const RunResult& r) {
  Time t;
  for (const Time& s : r.stage) {
    t.wall += s.wall;
    t.cpu += s.cpu;
  }
  return t;
}

/// Keeps the run with the smaller whole CPU time.
void keep_faster(RunResult* best, RunResult&& r, bool first) {
  if (first || total(r).cpu < total(*best).cpu) *best = std::move(r);
}

/// Each camera's solve of a run, repeated: the fastest (CPU time of this thread) per camera.
struct FastestSolves {
  double cpu_s = 0.0;  ///< summed over the cameras
  /// Per camera, the fastest solve's result with each part's fastest time over the repeats
  /// (a part's wall time is less disturbed by the other processes than the whole's).
  std::map<std::string, ext::EdgeAlignmentResult> results;
};

/// *fastest holds each part's minimum over the solves so far.
void keep_fastest_parts(const ext::EdgeAlignmentResult::StageTimes& t, ext::EdgeAlignmentResult::StageTimes* fastest) {
  using Times = ext::EdgeAlignmentResult::StageTimes;
  for (double Times::*part : {&Times::initial_guess_s, &Times::fields_s, &Times::paper_luts_s, &Times::alignment_s,
                              &Times::covariance_s})
    fastest->*part = std::min(fastest->*part, t.*part);
}

/// One method's fastest solve per camera so far.
class FastestOf {
 public:
  explicit FastestOf(ext::EdgeAlignmentMethod method) { options_.method = method; }
  void solve(const std::string& name, const std::vector<ext::TargetView>& views, const core::PinholeCamera& camera) {
    const double cpu0 = thread_cpu_s();
    ext::EdgeAlignmentResult result = ext::align_edges(views, camera, options_);
    const double cpu = thread_cpu_s() - cpu0;
    const bool first = best_cpu_.count(name) == 0;
    ext::EdgeAlignmentResult::StageTimes parts = first ? result.stage_times : parts_[name];
    keep_fastest_parts(result.stage_times, &parts);
    parts_[name] = parts;
    if (first || cpu < best_cpu_[name]) {
      best_cpu_[name] = cpu;
      out_.results[name] = std::move(result);
    }
  }
  FastestSolves result() const {
    FastestSolves out = out_;
    for (const auto& [name, cpu] : best_cpu_) {
      out.cpu_s += cpu;
      out.results[name].stage_times = parts_.at(name);
    }
    return out;
  }

 private:
  ext::EdgeAlignmentOptions options_;
  std::map<std::string, double> best_cpu_;
  std::map<std::string, ext::EdgeAlignmentResult::StageTimes> parts_;
  FastestSolves out_;
};

/// Each camera's solve by both methods, `repeats` times each, interleaved so that both see
/// the same machine (a spell of load on a shared one slows both, not one): the fastest of
/// each, ours in *ours, the paper's in *paper.
void fastest_solves(const RunResult& ours_run, const RunResult& paper_run,
                    const std::map<std::string, core::PinholeCamera>& cameras, int repeats, FastestSolves* ours,
                    FastestSolves* paper) {
  FastestOf ours_of(ext::EdgeAlignmentMethod::kSmoothField), paper_of(ext::EdgeAlignmentMethod::kPaperPlaneFit);
  for (int k = 0; k < repeats; ++k) {
    for (const auto& [name, views] : ours_run.views) ours_of.solve(name, views, cameras.at(name));
    for (const auto& [name, views] : paper_run.views) paper_of.solve(name, views, cameras.at(name));
  }
  *ours = ours_of.result();
  *paper = paper_of.result();
}

/// Each camera's solve by our method alone, `repeats` times in a row: the same solve with the
/// caches warm from the one before (the interleaved figure starts each after the paper's
/// LUTs flushed them, as detection does in a real run).
FastestSolves ours_back_to_back(const RunResult& ours_run, const std::map<std::string, core::PinholeCamera>& cameras,
                                int repeats) {
  FastestOf ours_of(ext::EdgeAlignmentMethod::kSmoothField);
  for (const auto& [name, views] : ours_run.views)
    for (int k = 0; k < repeats; ++k) ours_of.solve(name, views, cameras.at(name));
  return ours_of.result();
}

/// The solve's parts summed over the cameras [ms wall, each the fastest of the repeats]
/// (EdgeAlignmentResult::stage_times):
/// the initial guess, the exact fields and the covariance are the same code for both
/// methods; the paper's LUTs and each method's alignment rounds are its own.
void print_solve_parts(const FastestSolves& ours, const FastestSolves& paper) {
  using Times = ext::EdgeAlignmentResult::StageTimes;
  const auto sum = [](const FastestSolves& r, double Times::*part) {
    double s = 0.0;
    for (const auto& [name, res] : r.results) s += res.stage_times.*part;
    return 1e3 * s;
  };
  const std::pair<const char*, double Times::*> parts[] = {
      {"initial guess (shared)", &Times::initial_guess_s},
      {"exact edge fields (shared)", &Times::fields_s},
      {"paper's plane-fit LUTs", &Times::paper_luts_s},
      {"alignment (own method)", &Times::alignment_s},
      {"covariance (shared)", &Times::covariance_s}};
  std::printf("\n%-28s | %10s | %10s\n", "solve by part (wall, ms)", "ours", "paper");
  std::printf("%-28s | %10.2f | %10.2f\n", "whole solve (CPU)", 1e3 * ours.cpu_s, 1e3 * paper.cpu_s);
  for (const auto& [label, part] : parts) std::printf("%-28s | %10.2f | %10.2f\n", label, sum(ours, part), sum(paper, part));
  const double own_ours = sum(ours, &Times::alignment_s);
  const double own_paper = sum(paper, &Times::paper_luts_s) + sum(paper, &Times::alignment_s);
  std::printf("the methods' own parts (paper: LUTs + alignment; ours: alignment), paper / ours: %.0fx\n",
              own_paper / own_ours);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"calib_end_to_end: stage times of a whole calibration, ours and the paper's method, "
               "and the time of the rgbdt_calibrate app on the same session"};
  std::string session_dir;
  int views = 10, repeats = 3, solve_repeats = 20;
  std::uint64_t seed = 1;
  app.add_option("--session", session_dir, "calibration session folder (default: simulate one)");
  app.add_option("--views", views, "views of the simulated session")->capture_default_str();
  app.add_option("--seed", seed, "seed of the simulated session")->capture_default_str();
  app.add_option("--repeats", repeats, "runs of each; the fastest is reported")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--solve-repeats", solve_repeats,
                 "solves of each camera by each method on the same views, for the solve ratio; the fastest counts")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  const fs::path tmp = fs::temp_directory_path() / ("calib_end_to_end_" + std::to_string(getpid()));
  fs::create_directories(tmp / "out");
  if (session_dir.empty()) {
    rgbdt::sim::CalibrationSessionOptions o;
    o.views = views;
    o.seed = seed;
    session_dir = (tmp / "session").string();
    std::printf("simulating a %d-view calibration session (seed %llu) in %s...\n", views,
                static_cast<unsigned long long>(seed), session_dir.c_str());
    rgbdt::sim::write_calibration_session(session_dir, o);
  }
  const core::CalibrationSession session = core::read_calibration_session(session_dir);
  std::map<std::string, core::PinholeCamera> cameras;
  for (const auto& [name, entry] : session.cameras)
    cameras.emplace(name, core::PinholeCamera(core::read_camera_info(entry.intrinsics)));

  RunResult ours, paper;
  for (int k = 0; k < repeats; ++k) {
    keep_faster(&ours, run_pipeline(session, cameras, ext::EdgeAlignmentMethod::kSmoothField, tmp / "out"), k == 0);
    keep_faster(&paper, run_pipeline(session, cameras, ext::EdgeAlignmentMethod::kPaperPlaneFit, tmp / "out"), k == 0);
  }
  // The app itself, as a user runs it (automatic detection everywhere).
  const fs::path app_path = fs::read_symlink("/proc/self/exe").parent_path() / "rgbdt_calibrate";
  Time app_time;
  int app_exit = -1;
  for (int k = 0; k < repeats; ++k) {
    const Time t = time_child({app_path.string(), session_dir, "--out", (tmp / "app").string(), "--camera", "all",
                               "--seeds", "none"},
                              &app_exit);
    if (k == 0 || t.cpu < app_time.cpu) app_time = t;
  }

  std::printf("\n%zu views, cameras:", session.views.size());
  for (const auto& [name, c] : cameras) std::printf(" %s (%dx%d)", name.c_str(), c.width(), c.height());
  std::printf("\ntarget found: LIDAR %d/%zu views, images %d/%d; fastest of %d runs\n\n", ours.lidar_found,
              session.views.size(), ours.image_found, ours.image_total, repeats);
  std::printf("%-24s | %10s %10s | %10s %10s\n", "stage", "ours wall", "ours CPU", "paper wall", "paper CPU");
  for (int s = 0; s < kNumStages; ++s)
    std::printf("%-24s | %9.3fs %9.3fs | %9.3fs %9.3fs\n", kStageNames[static_cast<std::size_t>(s)],
                ours.stage[static_cast<std::size_t>(s)].wall, ours.stage[static_cast<std::size_t>(s)].cpu,
                paper.stage[static_cast<std::size_t>(s)].wall, paper.stage[static_cast<std::size_t>(s)].cpu);
  const Time to = total(ours), tp = total(paper);
  std::printf("%-24s | %9.3fs %9.3fs | %9.3fs %9.3fs\n", "whole run (in-process)", to.wall, to.cpu, tp.wall, tp.cpu);
  std::printf("%-24s | %9.3fs %9.3fs | (exit %d)\n", "rgbdt_calibrate app", app_time.wall, app_time.cpu, app_exit);
  FastestSolves ours_solves, paper_solves;
  fastest_solves(ours, paper, cameras, solve_repeats, &ours_solves, &paper_solves);
  const double ratio_cpu = paper_solves.cpu_s / ours_solves.cpu_s;
  std::printf("\nsolve, paper / ours: %.1fx CPU, the fastest of %d solves per camera (%.2f / %.2f ms; target >= 100x); "
              "in the runs above %.0fx\n",
              ratio_cpu, solve_repeats, 1e3 * paper_solves.cpu_s, 1e3 * ours_solves.cpu_s,
              paper.stage[kSolve].cpu / ours.stage[kSolve].cpu);
  const FastestSolves warm = ours_back_to_back(ours, cameras, solve_repeats);
  std::printf("ours back to back (warm caches): %.2f ms, paper / ours %.1fx\n", 1e3 * warm.cpu_s,
              paper_solves.cpu_s / warm.cpu_s);
  print_solve_parts(ours_solves, paper_solves);

  bool ok = ours.problem.empty() && app_exit == 0;
  const auto truth = read_truth(session_dir);
  for (const auto* run : {&ours, &paper}) {
    std::printf("%s: %s\n", run == &ours ? "ours " : "paper", run->problem.empty() ? "every camera calibrated" : run->problem.c_str());
    for (const auto& [name, res] : run->results) {
      std::printf("  %-8s RMS %.3f px", name.c_str(), res.rms_px);
      if (const auto t = truth.find(name); t != truth.end()) {
        const ext::PoseError e = ext::pose_error(res.T_camera_lidar, t->second);
        std::printf(", error vs ground truth %.4f deg, %.3f cm", e.rotation_deg, e.translation_cm);
      }
      std::printf("\n");
    }
  }
  // The time target is for one core: the app's CPU time (user + system) is what its wall
  // time is on an idle core, and unlike the wall time it is not inflated by other processes.
  const bool fast = app_time.cpu < 2.0;
  const bool ratio_ok = ratio_cpu >= 100.0;
  const bool all_found =
      ours.lidar_found == static_cast<int>(session.views.size()) && ours.image_found == ours.image_total;
  std::printf("verdict: app %s (%.2f s CPU, %.2f s wall; target < 2 s on one core); solve ratio %s (%.1fx CPU, "
              "target >= 100x); detections %s\n",
              fast ? "ok" : "TOO SLOW", app_time.cpu, app_time.wall, ratio_ok ? "ok" : "BELOW TARGET", ratio_cpu,
              all_found ? "all found" : "SOME MISSED");
  ok = ok && fast && ratio_ok && all_found;
  fs::remove_all(tmp / "out");
  if (!ok) std::printf("FAILED (see the verdict above); the session and the app's outputs are kept in %s\n", tmp.c_str());
  else fs::remove_all(tmp);
  return ok ? 0 : 1;
}
