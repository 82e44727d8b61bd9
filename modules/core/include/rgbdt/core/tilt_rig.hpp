#pragma once
/// \file
/// The tilting-LIDAR rig description shared by the simulator (which writes it) and the
/// tilt_lidar assembler (which reads it): `tilt_rig.yaml`, named by a mapping session as
/// `lidar: {rawlog: lidar.rawlog, rig: tilt_rig.yaml}`.
///
/// Frames. `lidar` is the frame of every assembled cloud and of T_camera_lidar: the tilt
/// motor's frame, x forward, y left, z up, origin on the tilt axis; the tilt axis is its
/// y axis and tilt angle phi > 0 pitches the scanner down (right-hand rule about +y).
/// `scanner` is the 2D scanner's own frame (beam i at angle theta_i in its x-y plane,
/// counter-clockwise from -aperture/2, as MRPT's CObservation2DRangeScan).
///
///   p_lidar = Ry(phi(t)) * T_axis_scanner * [r cos(theta), r sin(theta), 0]
///
/// T_axis_scanner holds the mount: the scanner's offset from the tilt axis and any
/// misalignment. Beam i of a scan stamped t_scan is measured at
/// t_scan + i * scan_period_s / steps_per_revolution (UTM-30LX: 25 ms, 1440 steps).
///
/// Raw stream (MRPT rawlog, observations only, one clock in seconds):
///   - CObservation2DRangeScan, sensorLabel "HOKUYO": one per scan, timestamp = time of
///     beam 0; invalid returns have validRange = 0.
///   - CObservationRawDAQ, sensorLabel "TILT_ENCODER": one per encoder sample, timestamp =
///     sample time, CNTRIN_double[0] = encoder count, AIN_double[0] = tilt angle [rad].
///   mrpt::Clock::toDouble(timestamp) is the session time in seconds.
///
/// YAML:
///   scanner: {beams: 1081, aperture_deg: 270, scan_period_s: 0.025,
///             steps_per_revolution: 1440, range_min_m: 0.1, range_max_m: 30.0}
///   motor:   {counts_per_revolution: 4096, zero_count: 0}
///   mount:   {translation: [0, 0, 0.05], rotation_rpy_deg: [0, 0, 0]}   # T_axis_scanner
#include <Eigen/Geometry>
#include <string>

namespace rgbdt::core {

struct ScannerSpec {
  int beams = 1081;
  double aperture_rad = 270.0 * M_PI / 180.0;
  double scan_period_s = 0.025;
  int steps_per_revolution = 1440;
  double range_min_m = 0.1;
  double range_max_m = 30.0;

  /// Angle of beam i in the scanner frame [rad].
  double beam_angle(int i) const {
    return -0.5 * aperture_rad + aperture_rad * i / static_cast<double>(beams - 1);
  }
  /// Time of beam i after the scan's timestamp [s].
  double beam_time_offset(int i) const { return i * scan_period_s / steps_per_revolution; }
  std::string validate() const;  ///< empty when valid, else the reason
};

struct TiltMotorSpec {
  double counts_per_revolution = 4096.0;  ///< encoder resolution
  double zero_count = 0.0;                ///< count at tilt angle 0
  double angle_from_count(double count) const {
    return (count - zero_count) * 2.0 * M_PI / counts_per_revolution;
  }
  double count_from_angle(double angle_rad) const {
    return zero_count + angle_rad * counts_per_revolution / (2.0 * M_PI);
  }
  std::string validate() const;
};

struct TiltRig {
  ScannerSpec scanner;
  TiltMotorSpec motor;
  Eigen::Isometry3d T_axis_scanner = Eigen::Isometry3d::Identity();  ///< mount at tilt 0

  /// The transform that maps scanner points into the lidar frame at tilt angle phi [rad].
  Eigen::Isometry3d T_lidar_scanner(double phi_rad) const {
    return Eigen::Isometry3d(Eigen::AngleAxisd(phi_rad, Eigen::Vector3d::UnitY())) * T_axis_scanner;
  }
};

/// Reads tilt_rig.yaml; missing sections keep their defaults. Every number must be finite
/// and physical (beams in [2, 100000], aperture in (0, 360] deg, scan period in (0, 10] s,
/// ranges in [0, 1000] m and increasing, counts per revolution in [1, 1e9], mount offset
/// within 10 m). Throws rgbdt::core::Error naming the file, the key path, the value and what
/// was expected.
TiltRig read_tilt_rig(const std::string& path);
/// Parses tilt_rig.yaml text; `source` names it in errors.
TiltRig parse_tilt_rig(const std::string& yaml_text, const std::string& source);
/// Writes atomically (rgbdt/core/output.hpp); throws rgbdt::core::Error naming the path.
void write_tilt_rig(const std::string& path, const TiltRig& rig);

}  // namespace rgbdt::core
