#pragma once
// Synthetic tilting-LIDAR streams from a known motion profile, with the ground-truth point
// of every beam, for the assembler and rawlog tests.
#include <cmath>
#include <cstdint>
#include <vector>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/tilt_lidar/assembler.hpp"

namespace rgbdt::test {

struct MotionProfile {
  double center_rad = 0.1;      ///< sweep centre
  double amplitude_rad = 0.35;  ///< +-20 deg
  double period_s = 1.2;        ///< one tilt = period / 2 = 600 ms (design.md)
  double phase_s = 0.0;
  double phi(double t) const { return center_rad + amplitude_rad * std::sin(2 * M_PI * (t - phase_s) / period_s); }
  /// Times of the extremes (reversals) in [t0, t1].
  std::vector<double> reversals(double t0, double t1) const {
    std::vector<double> out;
    for (int k = -2; k < 1000; ++k) {
      const double t = phase_s + period_s * (0.25 + 0.5 * k);
      if (t > t0 && t < t1) out.push_back(t);
    }
    return out;
  }
};

inline core::TiltRig test_rig() {
  core::TiltRig rig;  // UTM-30LX defaults, 4096-count encoder
  rig.T_axis_scanner = core::make_transform(
      core::rotation_from_rpy(0.5 * M_PI / 180, -1.0 * M_PI / 180, 0.3 * M_PI / 180), {0.02, 0.0, 0.05});
  return rig;
}

struct Stream {
  std::vector<tilt_lidar::Scan> scans;
  std::vector<tilt_lidar::EncoderSample> encoder;  // quantised to whole counts
  std::vector<double> counts;                       // raw counts of `encoder`
};

/// Range of beam i of scan k: a smooth, varied scene between 1.5 and 9.5 m.
inline float test_range(int k, int i) {
  return static_cast<float>(5.5 + 4.0 * std::sin(0.013 * i + 0.07 * k) * std::cos(0.0021 * i));
}

/// 40 Hz scans starting at scan_t0, 200 Hz encoder samples starting at 0, for duration_s.
inline Stream make_stream(const core::TiltRig& rig, const MotionProfile& m, double duration_s,
                          double scan_t0 = 0.0071, double encoder_rate_hz = 200.0) {
  Stream s;
  for (int k = 0;; ++k) {
    const double t = k / encoder_rate_hz;
    if (t > duration_s + 0.05) break;
    const double count = std::round(rig.motor.count_from_angle(m.phi(t)));
    s.encoder.push_back({t, rig.motor.angle_from_count(count)});
    s.counts.push_back(count);
  }
  for (int k = 0;; ++k) {
    const double t = scan_t0 + k * rig.scanner.scan_period_s;
    if (t + rig.scanner.scan_period_s > duration_s) break;
    tilt_lidar::Scan scan;
    scan.time_s = t;
    const int n = rig.scanner.beams;
    scan.ranges_m.resize(n);
    scan.valid.assign(n, 1);
    scan.intensity.resize(n);
    for (int i = 0; i < n; ++i) {
      scan.ranges_m[i] = test_range(k, i);
      scan.intensity[i] = static_cast<float>(i % 100);
      if ((i + k) % 37 == 0) scan.valid[i] = 0;  // no return
    }
    s.scans.push_back(std::move(scan));
  }
  return s;
}

/// Ground-truth lidar-frame point of a beam measured at time t with range r.
inline Eigen::Vector3d true_point(const core::TiltRig& rig, const MotionProfile& m, double t, int beam, double r) {
  const double th = rig.scanner.beam_angle(beam);
  return rig.T_lidar_scanner(m.phi(t)) * Eigen::Vector3d(r * std::cos(th), r * std::sin(th), 0.0);
}

/// Feeds the stream in arrival order (an encoder sample when taken, a scan when complete),
/// handing each batch of finished tilts to `take` as the assembler emits it.
template <typename Take>
void feed_each(tilt_lidar::Assembler& a, const Stream& s, Take&& take) {
  std::size_t e = 0;
  const double scan_len = a.rig().scanner.scan_period_s;
  for (const auto& scan : s.scans) {
    while (e < s.encoder.size() && s.encoder[e].time_s <= scan.time_s + scan_len) take(a.add_encoder_sample(s.encoder[e++]));
    take(a.add_scan(scan));
  }
  while (e < s.encoder.size()) take(a.add_encoder_sample(s.encoder[e++]));
  take(a.flush());
}

/// feed_each, keeping every tilt.
inline std::vector<tilt_lidar::TiltCloud> feed(tilt_lidar::Assembler& a, const Stream& s) {
  std::vector<tilt_lidar::TiltCloud> out;
  feed_each(a, s, [&out](std::vector<tilt_lidar::TiltCloud>&& v) {
    for (auto& c : v) out.push_back(std::move(c));
  });
  return out;
}

}  // namespace rgbdt::test
