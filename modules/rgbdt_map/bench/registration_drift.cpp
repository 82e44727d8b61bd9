// rgbdt_map_drift: how far the registration drifts over the 100 m sim street, on
// several seeds (one seed alone misleads: the error depends on where a bad registration
// first happens), and what the initial guess does to it. For each LIDAR-only sim session
// (rgbdt_sim mapping --no-images, 80 s at 1.25 m/s) it runs Odometry over the tilts:
//   lidar-only   the mapper's default: constant-velocity guess, LIDAR-only de-skew;
//   gyro-prior   Odometry::set_motion_prior with the true motion plus a random walk of
//                0.02 deg and 1 cm per tilt (a tactical-grade IMU and rough wheel odometry);
//   true-prior   the true motion as the prior: what is left is the registration itself;
//   pcl-gicp     LIDAR only with PCL's GICP instead of ours (same cost, no robust loss);
//   accurate     LIDAR only, rgbdt_mapper --accurate: the smooth start-up over 4 tilts
//                (RegistrationOptions::start_up_clouds), windows of 3 tilts on a smooth
//                curve (window_clouds) and the merged local map (merged_local_map_m) of
//                24 tilts (RegistrationOptions::accurate()).
//   map-at-truth the true motion as the prior and every cloud registered from, and placed
//                in the local map at, the true pose (RegistrationOptions::map_at_prior):
//                each pose's error is that one registration's own bias, none accumulated.
//                After the table, its mean pitch error per tilt for each sweep direction.
// and prints, per session and mode, the anchored RMSE (trajectory_rmse_m, the issue's
// number), the aligned error (trajectory_ate_m), the final position error, the height part
// of the anchored error, the poses' mean pitch error relative to the first pose and its
// standard deviation over the poses (each pose's attitude noise: the anchored error is
// mostly the first pose's share of it, times the distance travelled), and the registration's
// CPU time per tilt (Odometry::add alone, on this thread: reading the clouds is not counted),
// so that one run shows what each mode's accuracy costs on the street itself.
// Usage: rgbdt_map_drift [--seeds N] [--first-seed K] [--duration S] [--dir DIR]
//   sessions are written to DIR/seed<k> (default <tmp>/rgbdt_map_drift) and reused; seeds K
//   to K + N - 1 (K = 1), so that a choice made on seeds 1-14 can be checked on 15-28.
//        rgbdt_map_drift --session DIR
//   the same six modes on one session of assembled clouds with a ground truth
//   (DIR/clouds/index.csv, DIR/ground_truth/trajectory.csv), e.g. the bench's yard from
//   rgbdt_map_bench --write-session DIR.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/rgbdt_map/registration.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"
#include "rgbdt/sim/mapping_session.hpp"

using namespace rgbdt;
using namespace rgbdt::rgbdt_map;
namespace fs = std::filesystem;

namespace {

/// The true motion with a random walk added: per sqrt(second), scaled so that one 0.6 s
/// tilt gets `deg_per_tilt` and `m_per_tilt` (1 sigma per axis).
Trajectory noisy_prior(const Trajectory& truth, double deg_per_tilt, double m_per_tilt, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double per_sqrt_s = 1.0 / std::sqrt(0.6);
  std::vector<TimedPose> out{truth.poses().front()};
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const TimedPose& a = truth.poses()[i - 1];
    const TimedPose& b = truth.poses()[i];
    const double scale = std::sqrt(b.time_s - a.time_s) * per_sqrt_s;
    core::Vector6d e;
    for (int k = 0; k < 3; ++k) e[k] = deg_per_tilt * M_PI / 180.0 * scale * unit(rng);
    for (int k = 3; k < 6; ++k) e[k] = m_per_tilt * scale * unit(rng);
    out.push_back({b.time_s, out.back().T_world_lidar * (a.T_world_lidar.inverse() * b.T_world_lidar) *
                                 core::from_vector6(e)});
  }
  return Trajectory(out);
}

// CPU time of this thread [ms]: the cost on one core, whatever else runs on the machine.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

struct Row {
  double anchored_m, aligned_m, final_m;
  double vertical_m;  ///< the vertical part of anchored_m (RMS of the height error)
  double pitch_deg;   ///< mean pitch error of the poses, relative to the first pose
  double pitch_sd_deg;  ///< its standard deviation over the poses
  double ms_per_tilt;   ///< Odometry::add's CPU time per tilt
  /// Sums over the poses of the pitch error [deg] and its square, and their count, for
  /// even and odd clouds (the sim's two sweep directions).
  double sweep_sum[2] = {}, sweep_sum2[2] = {};
  int sweep_n[2] = {};
};

Row run(const fs::path& session, const Trajectory& truth, const Trajectory* prior, const RegistrationOptions& options) {
  Odometry odometry(options);
  if (prior) odometry.set_motion_prior(*prior);
  double add_ms = 0.0;
  for (const core::TimedFile& f : core::read_time_index((session / "clouds" / "index.csv").string())) {
    const cloud::Cloud tilt = *cloud::load_pcd(f.file).cloud;
    const double start = thread_cpu_ms();
    odometry.add(tilt, f.time_s);
    add_ms += thread_cpu_ms() - start;
  }
  const Trajectory& estimate = odometry.trajectory();
  const TimedPose& first = estimate.poses().front();
  const TimedPose& last = estimate.poses().back();
  const Eigen::Isometry3d T_truth_estimate = truth.pose_at(first.time_s) * first.T_world_lidar.inverse();
  const double final_m =
      ((T_truth_estimate * last.T_world_lidar).translation() - truth.pose_at(last.time_s).translation()).norm();
  // Where the anchored error lies: the truth moves on a level street, so a height error
  // that grows with distance is a pitch error of the whole map relative to the first pose.
  double vertical2 = 0.0, pitch_rad = 0.0, pitch2_rad2 = 0.0;
  Row row;
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    const TimedPose& p = estimate.poses()[k];
    const Eigen::Isometry3d T_truth = truth.pose_at(p.time_s);
    const Eigen::Isometry3d anchored = T_truth_estimate * p.T_world_lidar;
    const double dz = anchored.translation().z() - T_truth.translation().z();
    vertical2 += dz * dz;
    const double pitch = core::to_vector6(T_truth.inverse() * anchored)[1];
    pitch_rad += pitch;
    pitch2_rad2 += pitch * pitch;
    const double pitch_deg = pitch * 180.0 / M_PI;
    row.sweep_sum[k % 2] += pitch_deg;
    row.sweep_sum2[k % 2] += pitch_deg * pitch_deg;
    ++row.sweep_n[k % 2];
  }
  const auto n = static_cast<double>(estimate.size());
  const double mean_pitch = pitch_rad / n;
  row.anchored_m = trajectory_rmse_m(estimate, truth);
  row.aligned_m = trajectory_ate_m(estimate, truth);
  row.final_m = final_m;
  row.vertical_m = std::sqrt(vertical2 / n);
  row.pitch_deg = mean_pitch * 180.0 / M_PI;
  row.pitch_sd_deg = std::sqrt(std::max(0.0, pitch2_rad2 / n - mean_pitch * mean_pitch)) * 180.0 / M_PI;
  row.ms_per_tilt = add_ms / n;
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 7;
  int first_seed = 1;
  double duration_s = 80.0;
  fs::path dir = fs::temp_directory_path() / "rgbdt_map_drift";
  fs::path one_session;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--seeds" && i + 1 < argc) {
      seeds = std::atoi(argv[++i]);
    } else if (arg == "--first-seed" && i + 1 < argc) {
      first_seed = std::atoi(argv[++i]);
    } else if (arg == "--duration" && i + 1 < argc) {
      duration_s = std::atof(argv[++i]);
    } else if (arg == "--dir" && i + 1 < argc) {
      dir = argv[++i];
    } else if (arg == "--session" && i + 1 < argc) {
      one_session = argv[++i];
    } else {
      std::printf(
          "rgbdt_map_drift: registration drift on LIDAR-only sim streets, several seeds, six modes of\n"
          "guess and registration (see the top of bench/registration_drift.cpp).\n"
          "Usage: %s [--seeds N (7)] [--first-seed K (1): seeds K to K+N-1] [--duration S (80, the issue's\n"
          "       100 m at 1.25 m/s)] [--dir DIR]\n"
          "       %s --session DIR   (one session of clouds with ground truth: DIR/clouds/index.csv and\n"
          "                            DIR/ground_truth/trajectory.csv, e.g. rgbdt_map_bench --write-session)\n",
          argv[0], argv[0]);
      return arg == "--help" || arg == "-h" ? 0 : 2;
    }
  }
  if (!one_session.empty()) {
    for (const char* part : {"clouds/index.csv", "ground_truth/trajectory.csv"}) {
      if (!fs::exists(one_session / part)) {
        std::fprintf(stderr, "rgbdt_map_drift: --session %s: no %s there (expected a session of clouds with ground truth)\n",
                     one_session.c_str(), part);
        return 2;
      }
    }
    seeds = 1;
  }
  if (seeds < 1 || first_seed < 1 || !(duration_s > 5.0)) {
    std::fprintf(stderr, "rgbdt_map_drift: --seeds %d, --first-seed %d, --duration %g: expected >= 1, >= 1 and > 5 s\n",
                 seeds, first_seed, duration_s);
    return 2;
  }
  std::printf("%-6s %-11s %12s %12s %10s %11s %10s %13s %11s\n", "seed", "guess", "anchored m", "aligned m", "final m",
              "of it: z m", "pitch deg", "pitch sd deg", "ms / tilt");
  constexpr int kModes = 6;
  const char* modes[kModes] = {"lidar-only", "gyro-prior", "true-prior", "pcl-gicp", "accurate", "map-at-truth"};
  RegistrationOptions options[kModes];  // rgbdt_mapper's defaults, but:
  options[3].backend = IcpBackend::kGeneralized;
  options[4] = RegistrationOptions::accurate();
  options[5].map_at_prior = true;
  double sum[kModes][6] = {};
  double sweep_sum[2] = {}, sweep_sum2[2] = {};
  int sweep_n[2] = {};
  for (int seed = first_seed; seed < first_seed + seeds; ++seed) {
    const fs::path session = one_session.empty() ? dir / ("seed" + std::to_string(seed)) : one_session;
    if (!fs::exists(session / "ground_truth" / "trajectory.csv")) {
      std::printf("[simulating seed %d: %.0f s street, LIDAR only]\n", seed, duration_s);
      std::fflush(stdout);
      sim::MappingSessionOptions options;
      options.duration_s = duration_s;
      options.seed = static_cast<std::uint64_t>(seed);
      options.write_images = false;
      options.trajectory.speed_m_s = 1.25;
      sim::write_mapping_session(session.string(), options);
    }
    const Trajectory truth = read_trajectory_csv((session / "ground_truth" / "trajectory.csv").string());
    const Trajectory gyro = noisy_prior(truth, 0.02, 0.01, 1000u + static_cast<unsigned>(seed));
    const Trajectory* priors[kModes] = {nullptr, &gyro, &truth, nullptr, nullptr, &truth};
    for (int m = 0; m < kModes; ++m) {
      const Row r = run(session, truth, priors[m], options[m]);
      if (m == 5) {
        for (int d = 0; d < 2; ++d) {
          sweep_sum[d] += r.sweep_sum[d];
          sweep_sum2[d] += r.sweep_sum2[d];
          sweep_n[d] += r.sweep_n[d];
        }
      }
      sum[m][0] += r.anchored_m;
      sum[m][1] += r.aligned_m;
      sum[m][2] += r.vertical_m;
      sum[m][3] += r.pitch_deg;
      sum[m][4] += r.pitch_sd_deg;
      sum[m][5] += r.ms_per_tilt;
      std::printf("%-6d %-11s %12.4f %12.4f %10.4f %11.4f %10.3f %13.3f %11.1f\n", seed, modes[m], r.anchored_m,
                  r.aligned_m, r.final_m, r.vertical_m, r.pitch_deg, r.pitch_sd_deg, r.ms_per_tilt);
      std::fflush(stdout);
    }
  }
  for (int m = 0; m < kModes; ++m) {
    std::printf("%-6s %-11s %12.4f %12.4f %10s %11.4f %10.3f %13.3f %11.1f\n", "mean", modes[m], sum[m][0] / seeds,
                sum[m][1] / seeds, "", sum[m][2] / seeds, sum[m][3] / seeds, sum[m][4] / seeds, sum[m][5] / seeds);
  }
  // The sim's tilt k sweeps from the profile's start angle (up) down for even k, back up
  // for odd k; a cloud's index is its tilt's.
  std::printf("\nmap-at-truth: each registration's own pitch error, mean over the tilts of all seeds\n");
  const char* sweeps[2] = {"even clouds (sweeping down)", "odd clouds (sweeping up)"};
  for (int d = 0; d < 2; ++d) {
    if (sweep_n[d] < 2) continue;
    const double mean = sweep_sum[d] / sweep_n[d];
    const double sd = std::sqrt(std::max(0.0, sweep_sum2[d] / sweep_n[d] - mean * mean));
    std::printf("  %-28s %+8.4f deg  (standard error %.4f deg, %d tilts)\n", sweeps[d], mean,
                sd / std::sqrt(static_cast<double>(sweep_n[d])), sweep_n[d]);
  }
  return 0;
}
