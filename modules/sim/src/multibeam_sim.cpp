#include "rgbdt/sim/multibeam_sim.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/error.hpp"

namespace rgbdt::sim {

namespace {

constexpr double kDeg = M_PI / 180.0;

struct BeamReturn {
  bool valid = false;
  double range_m = 0.0;
  double intensity = 0.0;
};

/// One beam from the origin along unit `dir`: the centre ray and four rays at the rim of
/// the footprint (half the divergence away, along u and v). When their ranges differ by
/// more than the mixed-pixel gap, the return is their reflectivity-weighted mean range.
BeamReturn cast_beam(const Scene& scene, const Eigen::Vector3d& dir, const BeamModel& beam, double noise) {
  const Eigen::Vector3d u = dir.unitOrthogonal();
  const Eigen::Vector3d v = dir.cross(u);
  const double h = std::tan(0.5 * beam.divergence_rad);
  const Eigen::Vector3d rays[5] = {dir, (dir + h * u).normalized(), (dir - h * u).normalized(),
                                   (dir + h * v).normalized(), (dir - h * v).normalized()};
  const int count = beam.divergence_rad > 0.0 ? 5 : 1;
  const Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double weight_sum = 0.0, range_sum = 0.0, min_r = 1e9, max_r = -1e9, centre_r = -1.0, centre_signal = 0.0;
  for (int k = 0; k < count; ++k) {
    const std::optional<Hit> hit = scene.intersect(origin, rays[k], 1e-6, 1.5 * beam.range_max_m);
    if (!hit) continue;
    const double cos_inc = std::abs(hit->normal.dot(rays[k]));
    const double w = scene.material(hit->material).nir_reflectivity * cos_inc + 1e-9;
    weight_sum += w;
    range_sum += w * hit->distance;
    min_r = std::min(min_r, hit->distance);
    max_r = std::max(max_r, hit->distance);
    if (k == 0) {
      centre_r = hit->distance;
      centre_signal = w;
    }
  }
  BeamReturn out;
  if (weight_sum <= 0.0) return out;
  const bool mixed = count > 1 && max_r - min_r > beam.mixed_pixel_min_gap_m;
  double range = centre_r > 0.0 && !mixed ? centre_r : range_sum / weight_sum;
  range += beam.range_sigma_m * noise;
  if (range < beam.range_min_m || range > beam.range_max_m) return out;
  out.valid = true;
  out.range_m = range;
  out.intensity = 255.0 * std::min(1.0, centre_r > 0.0 ? centre_signal : weight_sum / count);
  return out;
}

cloud::PointXYZIRT make_point(const Eigen::Vector3d& dir, const BeamReturn& r, int ring, double t) {
  cloud::PointXYZIRT q;
  const Eigen::Vector3d p = r.range_m * dir;
  q.x = static_cast<float>(p.x());
  q.y = static_cast<float>(p.y());
  q.z = static_cast<float>(p.z());
  q.intensity = static_cast<float>(r.intensity);
  q.ring = static_cast<std::uint16_t>(ring);
  q.t = static_cast<float>(t);
  return q;
}

void finish_cloud(cloud::Cloud* cloud) {
  cloud->width = static_cast<std::uint32_t>(cloud->size());
  cloud->height = 1;
  cloud->is_dense = true;
}

}  // namespace

std::string BeamModel::validate() const {
  std::ostringstream os;
  if (!(range_sigma_m >= 0.0)) os << "range_sigma_m " << range_sigma_m << " must be >= 0";
  else if (!(divergence_rad >= 0.0 && divergence_rad < 0.1)) os << "divergence_rad " << divergence_rad << " must be in [0, 0.1)";
  else if (!(mixed_pixel_min_gap_m > 0.0)) os << "mixed_pixel_min_gap_m " << mixed_pixel_min_gap_m << " must be > 0";
  else if (!(range_min_m >= 0.0 && range_max_m > range_min_m))
    os << "range [" << range_min_m << ", " << range_max_m << "] m must satisfy 0 <= min < max";
  return os.str();
}

SpinningLidarOptions SpinningLidarOptions::preset(int rings) {
  SpinningLidarOptions o;
  o.rings = rings;
  if (rings == 16 || rings == 32) {
    o.fov_up_deg = 15.0;
    o.fov_down_deg = -15.0;
    o.azimuth_step_deg = 0.2;
  } else if (rings == 64) {
    o.fov_up_deg = 16.6;
    o.fov_down_deg = -16.6;
    o.azimuth_step_deg = 0.35;
    o.beam.divergence_rad = 0.0018;  // OS1: 0.1 deg
  } else {
    throw std::invalid_argument("spinning LIDAR: rings " + std::to_string(rings) + " must be 16, 32 or 64");
  }
  return o;
}

std::string SpinningLidarOptions::validate() const {
  std::ostringstream os;
  if (rings < 2 || rings > 128) os << "rings " << rings << " must be in [2, 128]";
  else if (!(fov_up_deg > fov_down_deg) || fov_up_deg > 60.0 || fov_down_deg < -60.0)
    os << "vertical FOV [" << fov_down_deg << ", " << fov_up_deg << "] deg must be increasing within +-60 deg";
  else if (!(azimuth_step_deg > 0.01 && azimuth_step_deg <= 5.0)) os << "azimuth_step_deg " << azimuth_step_deg << " must be in (0.01, 5]";
  else if (!(rotation_hz > 0.0)) os << "rotation_hz " << rotation_hz << " must be > 0";
  else return beam.validate();
  return os.str();
}

std::string DenseLidarOptions::validate() const {
  std::ostringstream os;
  if (!(fov_deg > 1.0 && fov_deg < 120.0)) os << "fov_deg " << fov_deg << " must be in (1, 120)";
  else if (!(points_per_s > 0.0)) os << "points_per_s " << points_per_s << " must be > 0";
  else if (!(duration_s > 0.0 && duration_s * points_per_s <= 2e7))
    os << "duration_s " << duration_s << " must be > 0 with at most 2e7 points in all";
  else if (!(prism_hz_1 != 0.0 && prism_hz_2 != 0.0 && prism_hz_1 != -prism_hz_2))
    os << "prism rates " << prism_hz_1 << ", " << prism_hz_2 << " Hz must be non-zero and not opposite";
  else return beam.validate();
  return os.str();
}

cloud::Cloud simulate_spinning(const Scene& scene, const SpinningLidarOptions& options, double half_azimuth_rad,
                               std::uint64_t seed) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("SpinningLidarOptions: " + why);
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double step = options.azimuth_step_deg * kDeg;
  const int half_steps = static_cast<int>(std::ceil(half_azimuth_rad / step));
  const double steps_per_rev = 360.0 / options.azimuth_step_deg;
  const double ring_step = (options.fov_up_deg - options.fov_down_deg) / (options.rings - 1);
  cloud::Cloud cloud;
  for (int a = -half_steps; a <= half_steps; ++a) {
    const double az = a * step;
    // Time within the revolution, from the first firing of this sector.
    const double t = (a + half_steps) / (steps_per_rev * options.rotation_hz);
    for (int ring = 0; ring < options.rings; ++ring) {
      const double el = (options.fov_down_deg + ring * ring_step) * kDeg;
      const Eigen::Vector3d dir(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const double noise = unit(rng);  // drawn for every beam: the stream does not depend on the scene
      const BeamReturn r = cast_beam(scene, dir, options.beam, noise);
      if (r.valid) cloud.push_back(make_point(dir, r, ring, t));
    }
  }
  finish_cloud(&cloud);
  return cloud;
}

cloud::Cloud simulate_dense(const Scene& scene, const DenseLidarOptions& options, std::uint64_t seed) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("DenseLidarOptions: " + why);
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const long n = static_cast<long>(options.duration_s * options.points_per_s);
  const double half_cone = 0.5 * options.fov_deg * kDeg;
  // Each pair of phases starts at a random angle so that clouds of different seeds differ.
  std::uniform_real_distribution<double> phase(0.0, 2.0 * M_PI);
  const double p1 = phase(rng), p2 = phase(rng);
  cloud::Cloud cloud;
  for (long k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / options.points_per_s;
    // Two counter-rotating prisms each deflect by half the cone: their sum traces a rosette.
    const double w1 = 2.0 * M_PI * options.prism_hz_1 * t + p1, w2 = 2.0 * M_PI * options.prism_hz_2 * t + p2;
    const double az = 0.5 * half_cone * (std::cos(w1) + std::cos(w2));
    const double el = 0.5 * half_cone * (std::sin(w1) + std::sin(w2));
    const Eigen::Vector3d dir = Eigen::Vector3d(1.0, std::tan(az), std::tan(el)).normalized();
    const double noise = unit(rng);
    const BeamReturn r = cast_beam(scene, dir, options.beam, noise);
    if (r.valid) cloud.push_back(make_point(dir, r, 0, t));
  }
  finish_cloud(&cloud);
  return cloud;
}

void save_pcd_without_ring(const std::string& path, const cloud::Cloud& cloud) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw core::Error(path, "cannot write PCD (is the folder there and writable?)");
  f << "# .PCD v0.7 - Point Cloud Data file format\n"
    << "VERSION 0.7\nFIELDS x y z intensity t\nSIZE 4 4 4 4 4\nTYPE F F F F F\nCOUNT 1 1 1 1 1\n"
    << "WIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
    << "\nDATA binary\n";
  for (const auto& p : cloud.points) {
    const float v[5] = {p.x, p.y, p.z, p.intensity, p.t};
    f.write(reinterpret_cast<const char*>(v), sizeof(v));
  }
  if (!f) throw core::Error(path, "cannot write PCD: write failed");
}

}  // namespace rgbdt::sim
