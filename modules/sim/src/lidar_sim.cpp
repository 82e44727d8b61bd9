#include "rgbdt/sim/lidar_sim.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "rgbdt/sim/camera_sim.hpp"

namespace rgbdt::sim {

namespace {

// Phase of t within its tilt: the tilt index k and the fraction f in [0, 1).
void tilt_phase(const TiltProfile& p, double t, long* k, double* f) {
  const double tau = (t - p.start_time_s) / p.tilt_duration_s;
  const double fl = std::floor(tau);
  *k = static_cast<long>(fl);
  *f = tau - fl;
}

}  // namespace

double TiltProfile::angle_rad(double t) const {
  long k = 0;
  double f = 0.0;
  tilt_phase(*this, t, &k, &f);
  const double s = shape == Shape::kTriangle ? f : 0.5 - 0.5 * std::cos(M_PI * f);
  const bool forward = (k % 2 + 2) % 2 == 0;
  return forward ? phi_start_rad + (phi_end_rad - phi_start_rad) * s : phi_end_rad + (phi_start_rad - phi_end_rad) * s;
}

double TiltProfile::velocity_rad_s(double t) const {
  long k = 0;
  double f = 0.0;
  tilt_phase(*this, t, &k, &f);
  const double ds_df = shape == Shape::kTriangle ? 1.0 : 0.5 * M_PI * std::sin(M_PI * f);
  const bool forward = (k % 2 + 2) % 2 == 0;
  return (forward ? 1.0 : -1.0) * (phi_end_rad - phi_start_rad) * ds_df / tilt_duration_s;
}

long TiltProfile::tilt_index(double t) const {
  // Scan times are sums of periods: a scan due exactly at a tilt boundary can land a few
  // ulps early; it belongs to the tilt that starts there.
  return static_cast<long>(std::floor((t - start_time_s) / tilt_duration_s + 1e-9));
}

std::string TiltProfile::validate() const {
  std::ostringstream os;
  if (!(tilt_duration_s > 0.0)) os << "tilt_duration_s " << tilt_duration_s << " must be positive";
  else if (!(std::abs(phi_end_rad - phi_start_rad) > 0.0)) os << "tilt range must not be empty";
  else if (std::abs(phi_start_rad) > M_PI_2 || std::abs(phi_end_rad) > M_PI_2) os << "tilt angles must be within +-90 deg";
  return os.str();
}

std::string TiltLidarOptions::validate() const {
  std::ostringstream os;
  for (const std::string& why : {rig.scanner.validate(), rig.motor.validate(), profile.validate()}) {
    if (!why.empty()) return why;
  }
  if (!(range_sigma_m >= 0.0)) os << "range_sigma_m " << range_sigma_m << " must be >= 0";
  else if (!(beam_divergence_rad >= 0.0)) os << "beam_divergence_rad " << beam_divergence_rad << " must be >= 0";
  else if (!(mixed_pixel_min_gap_m > 0.0)) os << "mixed_pixel_min_gap_m " << mixed_pixel_min_gap_m << " must be positive";
  else if (!(min_signal >= 0.0)) os << "min_signal " << min_signal << " must be >= 0";
  else if (!(intensity_scale > 0.0)) os << "intensity_scale " << intensity_scale << " must be positive";
  else if (!(encoder_rate_hz > 0.0)) os << "encoder_rate_hz " << encoder_rate_hz << " must be positive";
  else if (!(encoder_jitter_s >= 0.0)) os << "encoder_jitter_s " << encoder_jitter_s << " must be >= 0";
  return os.str();
}

TiltLidarSimulator::TiltLidarSimulator(const TiltLidarOptions& options, std::uint64_t seed)
    : options_(options), rng_(seed) {
  const std::string why = options_.validate();
  if (!why.empty()) throw std::invalid_argument("TiltLidarOptions: " + why);
}

RawScan TiltLidarSimulator::scan(const Scene& scene, double t_scan, const PoseFunction& T_world_lidar) {
  const core::ScannerSpec& spec = options_.rig.scanner;
  RawScan out;
  out.time_s = t_scan;
  out.range_m.assign(static_cast<size_t>(spec.beams), 0.0f);
  out.valid.assign(static_cast<size_t>(spec.beams), 0);
  out.intensity.assign(static_cast<size_t>(spec.beams), 0.0f);
  out.truth_temperature_k.assign(static_cast<size_t>(spec.beams), std::numeric_limits<float>::quiet_NaN());
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double half = 0.5 * options_.beam_divergence_rad;
  // Sub-rays across the beam's footprint: centre, then +-half in scan angle and elevation.
  const double offsets[5][2] = {{0, 0}, {-half, 0}, {half, 0}, {0, -half}, {0, half}};
  const int rays = options_.mixed_pixels && half > 0.0 ? 5 : 1;
  for (int i = 0; i < spec.beams; ++i) {
    const double t = t_scan + spec.beam_time_offset(i);
    const Eigen::Isometry3d T_world_scanner =
        T_world_lidar(t) * options_.rig.T_lidar_scanner(options_.profile.angle_rad(t));
    const Eigen::Vector3d origin = T_world_scanner.translation();
    const double theta = spec.beam_angle(i);
    double weight_sum = 0.0, range_sum = 0.0, min_r = 1e9, max_r = -1e9;
    std::optional<Hit> centre;
    bool one_material = true;  // every sub-ray that hit something hit the centre's material
    for (int k = 0; k < rays; ++k) {
      const double th = theta + offsets[k][0], el = offsets[k][1];
      const Eigen::Vector3d dir_scanner(std::cos(th) * std::cos(el), std::sin(th) * std::cos(el), std::sin(el));
      const std::optional<Hit> hit = scene.intersect(origin, T_world_scanner.linear() * dir_scanner, 1e-6,
                                                     spec.range_max_m * 1.5);
      if (k == 0) centre = hit;
      if (!hit) continue;
      if (!centre || hit->material != centre->material) one_material = false;
      const double cos_inc = std::abs(hit->normal.dot(T_world_scanner.linear() * dir_scanner));
      const double w = scene.material(hit->material).nir_reflectivity * cos_inc + 1e-9;
      weight_sum += w;
      range_sum += w * hit->distance;
      min_r = std::min(min_r, hit->distance);
      max_r = std::max(max_r, hit->distance);
    }
    // Draw every random number for every beam so the stream does not depend on the scene.
    const double noise = unit(rng_);
    const double drop_draw = uniform(rng_);
    const double intensity_noise = unit(rng_);
    if (weight_sum <= 0.0) continue;
    double range = centre ? centre->distance : range_sum / weight_sum;
    const bool mixed = rays > 1 && max_r - min_r > options_.mixed_pixel_min_gap_m;
    if (mixed) range = range_sum / weight_sum;
    // A footprint spread in range over one material (the ground at a grazing angle) still
    // has one true temperature; one straddling two materials has none.
    if (centre && one_material) {
      out.truth_temperature_k[static_cast<size_t>(i)] = static_cast<float>(apparent_temperature_k(scene, *centre));
    }
    // Reflectivity and incidence of the surface the beam centre hit (or the footprint's).
    double signal = 0.0;
    double dropout = 0.0;
    const Eigen::Vector3d dir_centre = T_world_scanner.linear() * Eigen::Vector3d(std::cos(theta), std::sin(theta), 0.0);
    if (centre) {
      const Material& m = scene.material(centre->material);
      signal = m.nir_reflectivity * std::abs(centre->normal.dot(dir_centre));
      dropout = m.lidar_dropout_probability;
    } else {
      signal = weight_sum / rays;
    }
    signal *= (10.0 / std::max(range, 0.1)) * (10.0 / std::max(range, 0.1));
    if (options_.dropouts && (drop_draw < dropout || signal < options_.min_signal)) continue;
    range += options_.range_sigma_m * noise;
    if (range < spec.range_min_m || range > spec.range_max_m) continue;
    out.range_m[static_cast<size_t>(i)] = static_cast<float>(range);
    out.valid[static_cast<size_t>(i)] = 1;
    const double intensity = options_.intensity_scale * std::min(signal, 10.0) * (1.0 + 0.02 * intensity_noise);
    out.intensity[static_cast<size_t>(i)] = static_cast<float>(std::max(0.0, intensity));
  }
  return out;
}

std::vector<RawScan> TiltLidarSimulator::scans(const Scene& scene, double t_begin, double t_end,
                                               const PoseFunction& T_world_lidar) {
  std::vector<RawScan> out;
  const double period = options_.rig.scanner.scan_period_s;
  for (long k = 0;; ++k) {
    const double t = t_begin + k * period;
    if (t >= t_end - 1e-12) break;
    out.push_back(scan(scene, t, T_world_lidar));
  }
  return out;
}

std::vector<EncoderSample> TiltLidarSimulator::encoder_samples(double t_begin, double t_end) {
  std::vector<EncoderSample> out;
  std::normal_distribution<double> unit(0.0, 1.0);
  const double dt = 1.0 / options_.encoder_rate_hz;
  double last = -1e300;
  for (long k = 0;; ++k) {
    const double nominal = t_begin + k * dt;
    if (nominal >= t_end - 1e-12) break;
    double t = nominal + options_.encoder_jitter_s * unit(rng_);
    t = std::max(t, last + 1e-6);  // timestamps stay increasing
    last = t;
    EncoderSample s;
    s.time_s = t;
    s.count = std::round(options_.rig.motor.count_from_angle(options_.profile.angle_rad(t)));
    s.angle_rad = options_.rig.motor.angle_from_count(s.count);
    out.push_back(s);
  }
  return out;
}

Eigen::Vector3d beam_point_lidar(const TiltLidarOptions& options, const RawScan& scan, int beam) {
  const core::ScannerSpec& spec = options.rig.scanner;
  const double t = scan.time_s + spec.beam_time_offset(beam);
  const double theta = spec.beam_angle(beam);
  const double r = scan.range_m[static_cast<size_t>(beam)];
  return options.rig.T_lidar_scanner(options.profile.angle_rad(t)) *
         Eigen::Vector3d(r * std::cos(theta), r * std::sin(theta), 0.0);
}

cloud::Cloud assemble_cloud(const TiltLidarOptions& options, const std::vector<RawScan>& scans) {
  cloud::Cloud cloud;
  const core::ScannerSpec& spec = options.rig.scanner;
  double t_first = 0.0;
  bool first = true;
  for (size_t j = 0; j < scans.size(); ++j) {
    const RawScan& s = scans[j];
    for (int i = 0; i < spec.beams && i < static_cast<int>(s.valid.size()); ++i) {
      if (!s.valid[static_cast<size_t>(i)]) continue;
      const double t = s.time_s + spec.beam_time_offset(i);
      if (first) {
        t_first = t;
        first = false;
      }
      const Eigen::Vector3d p = beam_point_lidar(options, s, i);
      cloud::PointXYZIRT q;
      q.x = static_cast<float>(p.x());
      q.y = static_cast<float>(p.y());
      q.z = static_cast<float>(p.z());
      q.intensity = s.intensity[static_cast<size_t>(i)];
      q.ring = static_cast<std::uint16_t>(j);
      q.t = static_cast<float>(t - t_first);
      cloud.push_back(q);
    }
  }
  cloud.width = static_cast<std::uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = true;
  return cloud;
}

std::vector<RawScan> scans_of_tilt(const TiltLidarOptions& options, const std::vector<RawScan>& scans, long index) {
  std::vector<RawScan> out;
  for (const RawScan& s : scans) {
    if (options.profile.tilt_index(s.time_s) == index) out.push_back(s);
  }
  return out;
}

}  // namespace rgbdt::sim
