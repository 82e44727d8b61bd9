#pragma once
/// \file
/// LIDARs other than the tilting 2D scanner, for calibration views of a static rig:
///   - spinning multi-beam (Velodyne VLP-16, Ouster OS1-64 like): N beams at fixed
///     elevations, one revolution per frame; points carry `ring` (beam index, 0 = lowest)
///     and `t` (time within the revolution);
///   - dense non-repetitive (Livox like): a rosette of two counter-rotating prisms, whose
///     pattern never repeats, accumulated over a configurable time; no ring field.
/// Every beam has a finite divergence: sub-rays across its footprint that hit surfaces at
/// different ranges (the rim of a hole and the wall behind) return their mixed,
/// reflectivity-weighted range, which moves rim points off the board and widens holes, as
/// real LIDARs do. Range noise is Gaussian.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

/// Beam footprint and noise shared by the LIDAR kinds.
struct BeamModel {
  double range_sigma_m = 0.01;                ///< Gaussian range noise [m]
  double divergence_rad = 0.003;              ///< full width of the beam's cone [rad]
  double mixed_pixel_min_gap_m = 0.05;        ///< sub-ray ranges closer than this: one surface
  double range_min_m = 0.3;
  double range_max_m = 100.0;
  std::string validate() const;
};

struct SpinningLidarOptions {
  int rings = 16;                 ///< 16, 32 or 64 beams
  double fov_up_deg = 15.0;       ///< elevation of the top beam
  double fov_down_deg = -15.0;    ///< elevation of the bottom beam
  double azimuth_step_deg = 0.2;  ///< horizontal resolution
  double rotation_hz = 10.0;      ///< one frame = one revolution
  BeamModel beam;
  /// VLP-16 (16 beams +-15 deg, 2 deg apart, 0.2 deg azimuth, 3 mrad), a 32-beam unit
  /// (+-15 deg, 0.97 deg apart) or OS1-64 (+-16.6 deg, 0.53 deg apart, 0.35 deg azimuth).
  /// Throws std::invalid_argument for other counts.
  static SpinningLidarOptions preset(int rings);
  std::string validate() const;
};

struct DenseLidarOptions {
  double fov_deg = 38.4;          ///< full cone of the rosette (Livox Mid-40)
  double points_per_s = 100000.0;
  double duration_s = 3.0;        ///< accumulation time of one cloud
  /// Rotation rates of the two prisms [Hz]; an irrational ratio never repeats the pattern.
  double prism_hz_1 = 122.3;
  double prism_hz_2 = -77.9;
  BeamModel beam{0.02, 0.0049, 0.05, 0.5, 100.0};  ///< Livox: 0.28 deg divergence, 2 cm
  std::string validate() const;
};

/// One revolution of a spinning LIDAR at the origin of the scene (LIDAR frame = world),
/// z up, in the direction +-half_azimuth_rad around +x (the rest of the revolution is not
/// simulated; a calibration target lies in front). Points: x y z intensity ring t.
cloud::Cloud simulate_spinning(const Scene& scene, const SpinningLidarOptions& options, double half_azimuth_rad,
                               std::uint64_t seed);

/// One accumulated cloud of a dense non-repetitive LIDAR looking along +x (ring = 0: the
/// cloud has no scan lines; write it without the field).
cloud::Cloud simulate_dense(const Scene& scene, const DenseLidarOptions& options, std::uint64_t seed);

/// Writes a binary PCD with fields x y z intensity t (no ring), as a driver of a LIDAR
/// without scan lines does. Throws rgbdt::core::Error naming the file on failure.
void save_pcd_without_ring(const std::string& path, const cloud::Cloud& cloud);

}  // namespace rgbdt::sim
