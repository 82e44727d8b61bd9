#pragma once
/// \file
/// Tilting 2D LIDAR (Hokuyo UTM-30LX on a Dynamixel tilt motor), with exactly the
/// geometry, frames and beam timing of rgbdt/core/tilt_rig.hpp:
///   p_lidar = Ry(phi(t)) * T_axis_scanner * [r cos(theta_i), r sin(theta_i), 0],
///   beam i of a scan stamped t_scan is measured at t_scan + i * scan_period / steps.
/// The rig moves along T_world_lidar(t) (constant for a static rig); each beam is cast
/// from where the scanner is at its own time.
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

/// Tilt angle over time. One tilt is a sweep from phi_start to phi_end taking
/// tilt_duration_s; the motor then sweeps back (the next tilt), and so on.
struct TiltProfile {
  enum class Shape {
    kTriangle,  ///< constant speed, instant reversal (position-controlled servo)
    kSine,      ///< sinusoidal (cosine-smoothed) sweep, zero speed at the ends
  };
  Shape shape = Shape::kTriangle;
  double phi_start_rad = -30.0 * M_PI / 180.0;  ///< angle at the start of tilt 0 (negative: up)
  double phi_end_rad = 30.0 * M_PI / 180.0;     ///< angle at the end of tilt 0
  double tilt_duration_s = 0.6;                 ///< one sweep [s]
  double start_time_s = 0.0;                    ///< time at which tilt 0 begins [s]

  double angle_rad(double t) const;       ///< phi(t)
  double velocity_rad_s(double t) const;  ///< dphi/dt
  /// Index of the tilt that contains time t (floor((t - start) / duration)).
  long tilt_index(double t) const;
  std::string validate() const;
};

struct TiltLidarOptions {
  core::TiltRig rig;              ///< scanner, encoder and mount (written to tilt_rig.yaml)
  TiltProfile profile;
  double range_sigma_m = 0.01;    ///< Gaussian range noise [m]
  /// Mixed pixels: the beam's footprint (a cone of this full width) straddles a depth
  /// edge and the scanner reports a range between the two surfaces.
  bool mixed_pixels = true;
  double beam_divergence_rad = 0.25 * M_PI / 180.0;
  double mixed_pixel_min_gap_m = 0.05;  ///< surfaces closer than this are not an edge
  bool dropouts = true;           ///< material dropouts and weak returns lose the point
  /// A return is lost when nir_reflectivity * |cos(incidence)| * (10 m / r)^2 is below this.
  double min_signal = 0.01;
  double intensity_scale = 3000.0;  ///< device units for a white surface at 10 m, facing
  double encoder_rate_hz = 100.0;   ///< encoder samples per second
  double encoder_jitter_s = 0.0;    ///< Gaussian jitter of encoder timestamps [s]
  std::string validate() const;
};

/// One 2D scan as the UTM-30LX reports it (MRPT's CObservation2DRangeScan convention:
/// beam i at rig.scanner.beam_angle(i), counter-clockwise).
struct RawScan {
  double time_s = 0.0;             ///< time of beam 0
  std::vector<float> range_m;      ///< 0 where invalid
  std::vector<char> valid;         ///< 1 = valid return
  std::vector<float> intensity;    ///< device units
  /// Ground truth, not part of the scanner's output: apparent temperature [K] of the surface
  /// the beam's centre hit (what a thermal camera sees there, apparent_temperature_k); NaN
  /// when the beam's centre hit nothing or its footprint straddled two materials (a mixed
  /// pixel lies between two surfaces and has no single true temperature).
  std::vector<float> truth_temperature_k;
};

struct EncoderSample {
  double time_s = 0.0;
  double count = 0.0;      ///< integer encoder count (quantised)
  double angle_rad = 0.0;  ///< angle of that count, TiltMotorSpec::angle_from_count
};

/// Pose of the LIDAR frame in the world over time.
using PoseFunction = std::function<Eigen::Isometry3d(double time_s)>;

class TiltLidarSimulator {
 public:
  /// Throws std::invalid_argument if options.validate() fails.
  TiltLidarSimulator(const TiltLidarOptions& options, std::uint64_t seed);
  const TiltLidarOptions& options() const { return options_; }

  /// Scan starting at t_scan.
  RawScan scan(const Scene& scene, double t_scan, const PoseFunction& T_world_lidar);
  /// Scans every scan period in [t_begin, t_end).
  std::vector<RawScan> scans(const Scene& scene, double t_begin, double t_end, const PoseFunction& T_world_lidar);
  /// Encoder samples at encoder_rate_hz in [t_begin, t_end), counts rounded to integers.
  std::vector<EncoderSample> encoder_samples(double t_begin, double t_end);

 private:
  TiltLidarOptions options_;
  std::mt19937_64 rng_;
};

/// Point of beam i of a scan in the LIDAR frame at the beam's time, using the true
/// tilt angle of the profile.
Eigen::Vector3d beam_point_lidar(const TiltLidarOptions& options, const RawScan& scan, int beam);

/// Assembles scans into one cloud in the LIDAR frame (x y z intensity ring t) with the
/// true tilt angle at every beam's time: ring = index of the scan in `scans`, t = time
/// from the cloud's first point. Invalid returns are skipped. As a real assembler, it does
/// not undo the rig's motion during the tilt.
cloud::Cloud assemble_cloud(const TiltLidarOptions& options, const std::vector<RawScan>& scans);

/// Scans whose timestamps lie in tilt `index` of the profile.
std::vector<RawScan> scans_of_tilt(const TiltLidarOptions& options, const std::vector<RawScan>& scans, long index);

}  // namespace rgbdt::sim
