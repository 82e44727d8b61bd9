// Is each hole's LIDAR uncertainty (lidar_hole_sigma: the centre in the board plane and
// along its normal, as rgbdt_calibrate gives it to the covariance) as large as the hole's
// true error? The input of the covariance consistency study (calib_consistency), one level
// down: simulated LIDAR views only (no images, no solve), so it runs in seconds.
//
//   cmake --build build --target lidar_hole_consistency && build/bin/lidar_hole_consistency
//   [--seeds 4]
//
// One row per LIDAR kind, board (1 or 4 holes) and range noise: the views where the target
// is found, the RMS true error of the hole centres and the RMS of their reported 1-sigma,
// in the plane (the larger axis, per axis) and along the normal, the mean of
// (error / sigma)^2 per degree of freedom, which is 1 when the sigma is honest, and the RMS
// of the sigma's beam-footprint term (fp_mm). With --range-noise 0.0001 the errors left are
// the footprint's. Exits 1 when a row's mean is above 3 (the sigma is less than 58 % of the
// error).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>

#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/extrinsics/covariance.hpp"
#include "rgbdt/sim/calibration_session.hpp"

namespace {

using namespace rgbdt;

struct Kind {
  const char* name;
  sim::LidarKind lidar;
  bool use_ring;
};

struct Row {
  int views = 0, found = 0, holes = 0;
  double err_plane2 = 0, sig_plane2 = 0, z2_plane = 0;
  double err_normal2 = 0, sig_normal2 = 0, z2_normal = 0;
  double footprint2 = 0;  ///< lidar_hole_sigma's footprint term, 0.5 b sin(incidence), squared
};

/// The true centre a detected hole belongs to: the nearest (the detector's layout order is
/// its own, as seen from the sensor).
Eigen::Vector3d true_center(const std::vector<Eigen::Vector3d>& truth, const Eigen::Vector3d& c) {
  Eigen::Vector3d best = truth.front();
  for (const auto& t : truth)
    if ((t - c).norm() < (best - c).norm()) best = t;
  return best;
}

void add_view(const sim::SimulatedLidarView& v, bool use_ring, const core::TargetSpec& target,
              Row* row) {
  ++row->views;
  const auto det = calib_targets::detect_target_in_cloud(v.cloud, use_ring && v.has_ring, target);
  if (!det.ok) return;
  ++row->found;
  for (const auto& h : det.holes) {
    const Eigen::Vector3d d = h.center - true_center(v.truth.hole_centers_lidar, h.center);
    const double along = d.dot(v.truth.normal_lidar);
    const double in_plane2 = (d - along * v.truth.normal_lidar).squaredNorm();
    const extrinsics::LidarHoleSigma s = extrinsics::lidar_hole_sigma(
        h.edge_points, det.board_points, h.center, h.normal, target.radius_m, h.edge_bias_m,
        det.point_spacing_m);
    const double sp2 = s.center_in_plane_m * s.center_in_plane_m,
                 sn2 = s.center_normal_m * s.center_normal_m;
    ++row->holes;
    const double sin_incidence = std::sqrt(std::max(0.0, 1.0 - std::pow(h.center.normalized().dot(h.normal), 2)));
    row->footprint2 += std::pow(0.5 * h.edge_bias_m * sin_incidence, 2);
    row->err_plane2 += in_plane2 / 2.0;
    row->sig_plane2 += sp2;
    row->z2_plane += in_plane2 / (2.0 * std::max(sp2, 1e-12));
    row->err_normal2 += along * along;
    row->sig_normal2 += sn2;
    row->z2_normal += along * along / std::max(sn2, 1e-12);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "lidar_hole_consistency: is each hole's LIDAR centre uncertainty as large as its true "
      "error?"};
  int seeds = 4, views = 3;
  double range_noise = -1.0;
  app.add_option("--seeds", seeds, "simulated sessions per row")->check(CLI::Range(1, 1000));
  app.add_option("--views", views, "views per session")->check(CLI::Range(1, 10));
  app.add_option("--range-noise", range_noise,
                 "LIDAR range noise 1-sigma [m] for every row instead of each LIDAR's default "
                 "times the row's scale (e.g. 0.0001: what remains is the beam footprint's part)")
      ->check(CLI::Range(0.0, 0.1));
  CLI11_PARSE(app, argc, argv);
  core::set_log_level(core::LogLevel::kError);

  const Kind kinds[] = {{"tilt-ring", sim::LidarKind::kTilt, true},
                        {"tilt-noring", sim::LidarKind::kTilt, false},
                        {"spinning16", sim::LidarKind::kSpinning16, true},
                        {"dense", sim::LidarKind::kDense, true}};
  std::printf("%-11s %5s %5s %7s %5s | %8s %8s %7s | %8s %8s %7s | %6s\n", "lidar", "holes", "noise",
              "found", "n", "err_mm", "sig_mm", "z2", "err_n_mm", "sig_n_mm", "z2_n", "fp_mm");
  bool honest = true;
  for (const Kind& kind : kinds) {
    for (int holes : {1, 4}) {
      for (double noise : {0.5, 1.0, 1.5}) {
        Row row;
        for (int seed = 1; seed <= seeds; ++seed) {
          sim::CalibrationSessionOptions opt;
          opt.views = views;
          opt.seed = static_cast<std::uint64_t>(seed);
          opt.noise_scale = noise;
          opt.holes = holes;
          opt.lidar = kind.lidar;
          opt.range_noise_m = range_noise;
          const core::TargetSpec target = sim::calibration_target(holes, holes == 1 ? 0.30 : 0.12);
          for (const auto& v : sim::simulate_lidar_views(opt))
            add_view(v, kind.use_ring, target, &row);
        }
        std::printf("%-11s %5d %5.2f %3d/%-3d %5d", kind.name, holes, noise, row.found, row.views,
                    row.holes);
        if (row.holes == 0) {
          std::printf(" | no hole found\n");
          continue;
        }
        const double n = row.holes;
        std::printf(" | %8.2f %8.2f %7.1f | %8.2f %8.2f %7.1f | %6.2f\n",
                    1e3 * std::sqrt(row.err_plane2 / n), 1e3 * std::sqrt(row.sig_plane2 / n),
                    row.z2_plane / n, 1e3 * std::sqrt(row.err_normal2 / n),
                    1e3 * std::sqrt(row.sig_normal2 / n), row.z2_normal / n,
                    1e3 * std::sqrt(row.footprint2 / n));
        honest = honest && row.z2_plane / n <= 3.0 && row.z2_normal / n <= 3.0;
      }
    }
  }
  std::printf("every row's mean (error / sigma)^2 <= 3: %s\n", honest ? "PASS" : "FAIL");
  return honest ? 0 : 1;
}
