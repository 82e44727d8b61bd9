#pragma once
/// \file
/// Mapping sessions (design.md / contracts.md): the rig on a cart driving down a street
/// (pavement, grass, buildings, trees, parked cars) at ~1 m/s along a smooth path.
///
/// Layout written to DIR:
///   session.yaml        lidar {rawlog, rig, clouds}, cameras rgb/thermal {intrinsics, frames,
///                       radiometry (thermal)}, trajectory
///   lidar.rawlog        raw scans + encoder samples (rgbdt/sim/rawlog.hpp)
///   tilt_rig.yaml       core::write_tilt_rig
///   clouds/index.csv    one assembled cloud per tilt (time of its first point), clouds/NNNNN.pcd
///   rgb/index.csv, rgb/NNNNN.png; thermal/index.csv, thermal/NNNNN.png (16-bit counts)
///   rgb.yaml thermal.yaml, ground_truth.yaml, true_calib/,
///   ground_truth/trajectory.csv   time_s,x,y,z,qx,qy,qz,qw of T_world_lidar
///   ground_truth/beam_temperature.png   true apparent temperature of every beam's surface
///                       (16-bit, row = scan, column = beam; ground_truth.yaml beam_temperature
///                       gives the scale and scan timing; 0 = no return, or a footprint on two
///                       materials), to score thermal colouring
/// Times are seconds on one clock, starting at start_time_s.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <string>

#include "rgbdt/sim/rig.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

/// Smooth cart path in the world (z up, ground at z = 0): forward along x at speed_m_s
/// with a lateral sine weave; the heading follows the path.
struct CartTrajectory {
  double speed_m_s = 1.0;
  double weave_amplitude_m = 0.6;
  double weave_period_s = 16.0;
  double start_time_s = 100.0;
  double lidar_height_m = 1.1;  ///< tilt axis above the ground
  /// T_world_lidar at time t (LIDAR x forward along the heading, z up).
  Eigen::Isometry3d T_world_lidar(double t) const;
};

/// An IMU in the LIDAR's axes (a MEMS part such as the BMI088): white noise per sample
/// (noise density x sqrt(rate)) and a constant gyro bias drawn per seed, all times the
/// session's noise multiplier.
struct SimImu {
  double rate_hz = 0.0;                         ///< 0: no IMU
  double gyro_noise_density = 0.014 * M_PI / 180.0;  ///< [rad/s/sqrt(Hz)]
  double gyro_bias_sigma_rad_s = 0.2 * M_PI / 180.0;
  double accel_noise_density = 175e-6 * 9.80665;  ///< [m/s^2/sqrt(Hz)]
};

struct MappingSessionOptions {
  double duration_s = 10.0;
  std::uint64_t seed = 1;
  TimeOfDay time_of_day = TimeOfDay::kDay;
  double noise_scale = 1.0;
  int supersampling = 2;        ///< edges of mapping frames need less than calibration ones
  bool write_images = true;
  CartTrajectory trajectory;
  RigSpec rig;                  ///< camera rates: rig.rgb_fps, rig.thermal_fps
  /// imu.rate_hz > 0: imu.csv (time_s,wx,wy,wz,ax,ay,az from the true motion, noisy) named
  /// by session.yaml's imu.
  SimImu imu;
  std::string validate() const;
};

struct MappingSessionResult {
  std::string directory;
  int scans = 0, encoder_samples = 0, clouds = 0, rgb_frames = 0, thermal_frames = 0;
};

/// The street scene of mapping sessions (deterministic for a seed), long enough for
/// length_m of driving along +x from the origin.
Scene make_street_scene(double length_m, TimeOfDay time_of_day, std::uint64_t seed);

MappingSessionResult write_mapping_session(const std::string& out_dir, const MappingSessionOptions& options);

/// Paper Sec. 4.4: a white card before a wet black cloth at 5, 7.5, 10, 12 and 15 m, one
/// view (tilt + RGB + thermal frame) per depth, as a mapping session with assembled
/// clouds only (lidar {clouds}), frames at the same times as the clouds, and the card's
/// geometry per view in ground_truth.yaml (coloring_setup: ...).
struct ColoringSetupOptions {
  std::vector<double> depths_m = {5.0, 7.5, 10.0, 12.0, 15.0};
  Eigen::Vector2d card_size_m{0.9, 0.6};  ///< width, height
  std::uint64_t seed = 1;
  double noise_scale = 1.0;
  int supersampling = 8;
  double tilt_duration_s = 2.0;   ///< slow tilt of the static rig: dense scan lines
  double tilt_half_range_deg = 15.0;
  RigSpec rig;
  std::string validate() const;
};

MappingSessionResult write_coloring_setup(const std::string& out_dir, const ColoringSetupOptions& options);

}  // namespace rgbdt::sim
