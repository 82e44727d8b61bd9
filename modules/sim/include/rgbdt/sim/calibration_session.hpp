#pragma once
/// \file
/// Calibration sessions (contracts.md): the circle-hole target (white board, one or four
/// holes) in front of a wet black cloth at varied poses 3-8 m from a static rig, one
/// assembled LIDAR tilt and one RGB and one thermal image per view, with ground truth.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/sim/rig.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

/// The LIDAR that scans the target (multibeam_sim.hpp for the models).
enum class LidarKind {
  kTilt,        ///< the rig's tilting 2D Hokuyo, one tilt per view (ring = scan index)
  kSpinning16,  ///< VLP-16 like, one revolution per view (ring = beam)
  kSpinning32,  ///< 32 beams over +-15 deg
  kSpinning64,  ///< OS1-64 like
  kDense,       ///< Livox-like non-repetitive rosette accumulated over dense_duration_s, no ring field
};

/// "tilt", "spinning16", "spinning32", "spinning64", "dense".
std::string to_string(LidarKind kind);
/// Inverse of to_string; throws std::invalid_argument naming the value and the choices.
LidarKind lidar_kind_from_string(const std::string& name);

struct CalibrationSessionOptions {
  int views = 10;
  std::uint64_t seed = 1;
  /// Multiplies every noise of the rig: LIDAR range sigma, image noise, NETD, fixed pattern.
  double noise_scale = 1.0;
  int holes = 1;                ///< 1 (the paper's target) or 4 (2 x 2 board)
  double hole_radius_m = 0.0;   ///< 0: 0.30 m for 1 hole, 0.12 m for 4 holes
  double min_distance_m = 3.0;  ///< board centre distance from the LIDAR
  double max_distance_m = 8.0;
  double cloth_gap_m = 1.2;     ///< board to cloth distance
  int supersampling = 8;        ///< N x N sub-samples at image edges
  /// A static rig can tilt slowly: a slower sweep gives denser scan lines on the target.
  double tilt_duration_s = 2.0;
  double tilt_half_range_deg = 30.0;
  TimeOfDay time_of_day = TimeOfDay::kDay;
  double start_time_s = 100.0;  ///< session clock at view 0 [s]
  RigSpec rig;                  ///< true rig; noise levels are scaled by noise_scale
  LidarKind lidar = LidarKind::kTilt;
  /// LIDAR range noise sigma [m]; < 0: the LIDAR kind's own (tilt 0.01 m, spinning 0.01 m,
  /// dense 0.02 m) times noise_scale.
  double range_noise_m = -1.0;
  double dense_duration_s = 3.0;  ///< accumulation time of a dense cloud [s] (100k points/s)
  std::string validate() const;
};

/// Truth of one view.
struct CalibrationViewTruth {
  Eigen::Isometry3d T_lidar_board;  ///< board frame: centre, x right, y up, z towards the sensors
  std::vector<Eigen::Vector3d> hole_centers_lidar;
  Eigen::Vector3d normal_lidar;     ///< unit, towards the LIDAR
  double time_s = 0.0;
};

struct CalibrationSessionResult {
  std::string directory;
  core::TargetSpec target;
  std::vector<CalibrationViewTruth> views;
  int pose_attempts = 0;  ///< board poses drawn to find views that pass the visibility checks
};

/// The LIDAR cloud of one simulated view and its truth, without camera images.
struct SimulatedLidarView {
  CalibrationViewTruth truth;
  cloud::Cloud cloud;
  bool has_ring = true;  ///< false for kinds without scan lines (the PCD has no ring field)
};

/// The views of write_calibration_session (same poses and clouds for the same options),
/// without rendering or writing anything: for detector tests and studies.
std::vector<SimulatedLidarView> simulate_lidar_views(const CalibrationSessionOptions& options);

/// Board frame hole centres (row-major, top-left first as seen from the sensors) and board
/// size of the target with `holes` holes of radius_m.
core::TargetSpec calibration_target(int holes, double radius_m);

/// Builds the scene of one view: ground, the target at T_world_board and the cloth behind
/// it (world = LIDAR frame of the static rig). The target is primitive 1, the cloth 2.
Scene make_calibration_scene(const core::TargetSpec& target, const Eigen::Isometry3d& T_lidar_board,
                             double cloth_gap_m, TimeOfDay time_of_day);

/// Writes a complete calibration session into out_dir (created if needed). Throws
/// std::invalid_argument for bad options and rgbdt::core::Error for I/O failures.
CalibrationSessionResult write_calibration_session(const std::string& out_dir,
                                                   const CalibrationSessionOptions& options);

}  // namespace rgbdt::sim
