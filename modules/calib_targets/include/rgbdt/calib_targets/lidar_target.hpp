#pragma once
/// \file
/// The circular-hole target in a LIDAR cloud: paper Sec. 3.4-3.5, Algorithms 2 and 3.
///
/// Algorithm 2 (seeded): SAC plane segmentation of the points within `seed_radius_m` of the
/// seed, keep the part that contains the seed, RANSAC re-fit with a 2 cm threshold, then
/// theta discontinuities along each scan line give the hole's edge points.
/// Algorithm 3 (fixed): the printed cost Eq. (1) is not a least-squares problem; here the
/// centre c is constrained to the board plane and the known radius r is used, minimising
/// sum_i (|p_i - c|^2 - r^2)^2 with Ceres; the circle is then sampled at 1 degree steps.
///
/// Beyond the paper: no seed needed (the board is searched among the cloud's planes as a
/// segment with empty discs of the target's radius in its known layout); scan lines come
/// from `ring` or are recovered from the beams' elevation; and a detector that needs no
/// scan lines at all (edges of the board's in-plane occupancy, for non-repetitive LIDARs).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/session.hpp"

namespace rgbdt::calib_targets {

enum class LidarEdgeMethod {
  /// Measured from the cloud: scan lines when the board's points lie on lines (ring field,
  /// else lines recovered from the elevations), "sparse" when only 2-4 lines cross a hole,
  /// occupancy for dense clouds without lines (non-repetitive LIDARs, accumulated clouds).
  kAuto,
  kScanLines,  ///< Algorithm 2: theta discontinuities along each scan line
  kOccupancy,  ///< inner border of the board's in-plane occupancy around each empty disc
};

struct LidarDetectionOptions {
  /// Algorithm 2 input R: points within this distance of the seed are considered. Must
  /// cover the board. 0 = derived from the target (board half-diagonal + 0.3 m).
  double seed_radius_m = 0.0;
  /// First SAC plane segmentation threshold (Algorithm 2, line 1).
  double sac_distance_m = 0.03;
  /// RANSAC re-fit threshold delta (Algorithm 2, line 6; the paper's 2 cm). Raise it for
  /// noisier LIDARs (about 2.5x the range noise sigma).
  double refit_distance_m = 0.02;
  /// Theta discontinuity (Algorithm 2, line 17) as a multiple of the line's median angular
  /// step; the paper's fixed delta-theta is `min_theta_gap_rad`.
  double theta_gap_factor = 2.5;
  double min_theta_gap_rad = 0.0;  ///< lower bound of the discontinuity [rad]
  /// Elevation gap that separates two recovered scan lines when `ring` is absent [rad];
  /// 0 = automatic (half the median gap between distinct elevations).
  double scan_line_gap_rad = 0.0;
  LidarEdgeMethod edge_method = LidarEdgeMethod::kAuto;
  /// Automatic search: planar segments by region growing on normals (angle between
  /// neighbouring normals below this), then the range of interest.
  double smoothness_deg = 6.0;
  double min_range_m = 0.5;
  double max_range_m = 15.0;
  double search_voxel_m = 0.05;  ///< voxel of the downsampled copy used to find planes
  int min_board_points = 60;   ///< fewer points on a plane segment: not a board
  int min_edge_points = 4;     ///< fewer edge points for a hole: hole rejected
  /// Raster cell of the occupancy map [m]; 0 = automatic (from the point spacing).
  double grid_cell_m = 0.0;
  /// Edge points are moved by half the local point spacing towards the hole, because the
  /// last point on the board lies on average half a step outside the true edge.
  bool half_step_correction = true;
  /// Up direction of the LIDAR frame, used to order the holes (row-major, top-left first
  /// as seen from the sensor) and to resolve symmetric layouts.
  Eigen::Vector3d up_lidar = Eigen::Vector3d::UnitZ();
  /// A hole is accepted when its free-radius fit is within this fraction of the known
  /// radius and the RMS of the edges about the known circle is below max_rms_fraction * r.
  double max_radius_error = 0.25;
  double max_rms_fraction = 0.25;
  double circle_step_deg = 1.0;  ///< Algorithm 3 output resolution delta-theta
  /// Edge bias correction: a beam of finite divergence that partly hits the rim returns a
  /// mixed range, so rim points leave the board and holes look wider (and the half-step
  /// correction leaves a residual). The bias (mean free radius - known radius over the holes
  /// whose edges surround them) is estimated per view and the centres are refitted with the
  /// known radius plus the bias, so that chords of a few scan lines do not pull a centre
  /// towards them.
  bool correct_edge_bias = true;
  /// Full beam divergence [rad] of the LIDAR, when known: gives the bias (half the footprint
  /// at the hole's range) of views where no hole is surrounded by edges. 0 = unknown.
  double beam_divergence_rad = 0.0;
  /// Fitted hole centres must reproduce the layout's pairwise distances within
  /// max(layout_tolerance_m, 0.25 r); else the board is rejected (never a wrong target).
  double layout_tolerance_m = 0.03;

  /// Empty when usable, else the reason naming the value.
  std::string validate() const;
};

struct LidarHole {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< [m] LIDAR frame
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX(); ///< unit, pointing towards the sensor
  double radius_m = 0.0;  ///< radius from a free-radius fit of the edges [m] (see below)
  /// False when the edges do not surround the hole (e.g. one scan line crosses it): then
  /// radius_m is the target's known radius, not a measurement.
  bool radius_measured = false;
  std::vector<Eigen::Vector3d> edge_points;    ///< detected edge points (Algorithm 2) [m]
  std::vector<Eigen::Vector3d> circle_points;  ///< generated circle, known radius (Algorithm 3)
  double rms_m = 0.0;  ///< RMS distance of the edge points to the known-radius circle [m]
  /// Edge bias applied to this hole's centre fit [m] (the centre is fitted with radius
  /// r + edge_bias_m; circle_points keep the known radius r).
  double edge_bias_m = 0.0;
  int lines_across = 0;  ///< scan lines with edges on this hole (0 for occupancy edges)
};

struct LidarTargetDetection {
  bool ok = false;
  std::string reason;  ///< why detection failed (ok == false)
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();  ///< n.x + d = 0, n towards the sensor
  std::vector<LidarHole> holes;  ///< in layout order (row-major, top-left first)
  std::vector<Eigen::Vector3d> board_points;  ///< the plane segment C (Algorithm 2, line 6)
  /// How the edges were found: "scan_lines (ring)", "scan_lines (recovered)", "sparse_lines
  /// (ring)" / "sparse_lines (recovered)" (2-4 lines across a hole), "occupancy" (no lines),
  /// with "+occupancy" when some holes fell back to it.
  std::string edge_method;
  /// What the detector measured to choose the method, e.g. "12034 board points, spacing
  /// 0.011 m, ring field, 3-5 lines across a hole".
  std::string cloud_profile;
  /// Median distance between neighbouring board points in the board plane [m]: how far
  /// the true edge may lie beyond the last board point before a hole.
  double point_spacing_m = 0.0;
  double edge_bias_m = 0.0;       ///< the view's edge bias applied to every hole [m]
  std::string edge_bias_source;   ///< "measured on N hole(s)", "beam divergence model", "none"
};

/// Detects the circle target. `has_ring` says whether the cloud's ring field is valid
/// (cloud::LoadedCloud::has_ring). With a seed, Algorithm 2 runs on the points around it;
/// without, the board is searched automatically. Never throws for bad data: ok = false
/// and `reason` say what is wrong. Throws std::invalid_argument for invalid options/target.
LidarTargetDetection detect_target_in_cloud(const cloud::Cloud& cloud, bool has_ring,
                                            const core::TargetSpec& target,
                                            const LidarDetectionOptions& options = {},
                                            std::optional<Eigen::Vector3d> seed = {});

/// Algorithm 3 (fixed): centre of a circle of known radius in the plane (n, point on plane
/// `origin`) fitted to edge points with Ceres. Returns the centre; rms_m receives the RMS of
/// |p - c| - r. Exposed for tests and for other targets.
Eigen::Vector3d fit_circle_center_in_plane(const std::vector<Eigen::Vector3d>& edge_points,
                                           const Eigen::Vector3d& normal,
                                           const Eigen::Vector3d& origin, double radius_m,
                                           const Eigen::Vector3d& initial_center,
                                           double* rms_m = nullptr);

/// Algorithm 3, lines 5-14: points of the circle (centre, unit normal, radius) every step_deg.
std::vector<Eigen::Vector3d> sample_circle(const Eigen::Vector3d& center,
                                           const Eigen::Vector3d& normal, double radius_m,
                                           double step_deg = 1.0);

/// Hole centres of the target on the board [m], board frame (x right, y up); a single
/// centred hole when target.holes_m is empty.
std::vector<Eigen::Vector2d> target_layout(const core::TargetSpec& target);

}  // namespace rgbdt::calib_targets
