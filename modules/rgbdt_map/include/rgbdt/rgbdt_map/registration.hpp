#pragma once
/// \file
/// Registration of successive tilt clouds into one trajectory (paper Sec. 5: "our 3D
/// mapping pipeline (which is implemented using the Iterative Closest Point [4]
/// algorithm)"). Each new cloud is de-skewed with the constant-velocity model (a tilt
/// lasts 600 ms, during which the cart moves), registered against a local map made of the
/// previous clouds (so also against its predecessor), starting from the constant-velocity
/// prediction.
///
/// Implemented in src/: registration.cpp (to_string, RegistrationOptions, downsample,
/// register_clouds, deskew, points_in_world, sensor_origins_in_world), robust_gicp.cpp
/// (IcpBackend::kRobust and GICP's covariances), trajectory_curve.cpp (the smooth-curve solve
/// behind RegistrationOptions::start_up_clouds and window_clouds), odometry.cpp (Odometry);
/// registration_internal.hpp declares what they share.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"

namespace rgbdt::rgbdt_map {

namespace detail {
struct TimedPoints;  ///< a tilt's voxel centroids with their times (odometry.cpp)
}  // namespace detail


enum class IcpBackend {
  kRobust,        ///< ours: GICP's plane-to-plane cost, Gauss-Newton with a Cauchy loss
  kGeneralized,   ///< pcl::GeneralizedIterativeClosestPoint (plane-to-plane)
  kPointToPoint,  ///< pcl::IterativeClosestPoint
};
const char* to_string(IcpBackend backend);
/// "rgicp", "gicp" or "icp"; throws std::invalid_argument naming the value otherwise.
IcpBackend icp_backend_from_string(const std::string& name);

struct RegistrationOptions {
  /// Ours (kRobust), chosen on bench/registration_drift.cpp: on 7 LIDAR-only 100 m sim
  /// streets the aligned trajectory error is 1.2-2.4 cm, against 7-28 cm with PCL's GICP on
  /// the same cost. PCL's GICP has no robust loss: points at the front of a tilt, beyond
  /// what the local map has seen, take wrong neighbours within the gate and move the
  /// minimum, so its result depends on the guess. PCL's GICP in turn beats point-to-point
  /// ICP and MRPT's CICP (bench/rgbdt_map_bench.cpp).
  IcpBackend backend = IcpBackend::kRobust;
  /// kRobust: squared Mahalanobis distance at which a correspondence's weight halves
  /// (Cauchy loss). With GICP's plane covariances (normal variance 2 x 0.001 m^2) 1 is a
  /// ~4.5 cm offset along the normal.
  double robust_scale2 = 1.0;
  /// 0 (off) or > 0: once settled_from_cloud clouds have come, robust_scale2 (the Cauchy scale
  /// of kRobust and of the smooth-curve solves) tightens to this for every later registration
  /// and window, but for each tilt's first run, which only sets the de-skew and converges
  /// faster with the loose scale (Odometry::add). The first tilts need the loose scale: their
  /// de-skew is guessed and the local map is one or two tilts, so their residuals are larger
  /// than the LIDAR's noise.
  /// Once the map has formed, the tighter scale measured better: with the loose one the
  /// registration carries a pitch bias (docs/mapping.md, "The pitch bias"; its cause is not
  /// measured). On the 14 LIDAR-only 100 m sim streets of docs/mapping.md,
  /// 0.1 after the 10th cloud: --accurate mean anchored 0.029 against 0.033 m, aligned 0.0042
  /// against 0.0068 m (lower on every street), the mean pitch error 0.00 against 0.02 deg,
  /// for 1-7 % more time (two runs); with the true motion as prior 0.033 against 0.046 m (0.1 throughout);
  /// the default 0.066 against 0.077 m for ~20 % more time, so off there. 0.1 on every
  /// tilt turned three LIDAR-only streets' first heading (0.17-0.30 m anchored).
  double settled_robust_scale2 = 0.0;
  int settled_from_cloud = 10;  ///< see settled_robust_scale2
  /// Clouds (the new tilt and every cloud of the local map) are voxel-downsampled to this
  /// before registration. [m]
  double source_voxel_m = 0.25;
  double max_correspondence_m = 1.0;  ///< correspondence gate; > expected prediction error [m]
  /// Outer iterations (correspondence updates; ours: Gauss-Newton steps, each with new
  /// correspondences).
  int max_iterations = 30;
  /// Converged when an iteration moves the estimate by less than this (PCL GICP: largest
  /// change of a translation component; ICP: translation norm; ours: the step's translation
  /// norm, or when its steps, each below this, bring the pose back to where it was 2-4 steps
  /// before: the correspondences then cycle between sets whose minima lie hundredths of a
  /// millimetre apart). 0.1 mm is 20x below the noise floor of the registration tests. [m]
  double translation_epsilon_m = 1e-4;
  /// ... and rotates it by less than this (PCL GICP: largest change of a rotation matrix
  /// element, ~ the angle; ours: a tenth of it, as the step's angle; a test 10x tighter
  /// gives the same trajectories in more steps: robust_gicp.cpp). [rad]
  double rotation_epsilon_rad = 1e-4;
  /// GICP and ours: neighbours that estimate each point's covariance (PCL's
  /// k_correspondences).
  /// 20 (PCL's default) measured more accurate than 10 on the odometry test (2.5 vs 3.9 cm
  /// at the eighth tilt) for ~10% more time.
  int covariance_neighbours = 20;
  /// PCL GICP only: BFGS iterations per outer iteration (PCL's default: 20).
  int optimizer_iterations = 20;
  /// The tilt is de-skewed with the predicted velocity, registered, and, if the result
  /// differs from the prediction by more than this (translation + rotation seen at 10 m),
  /// de-skewed again with the measured velocity and registered once more. Below it the
  /// de-skew error is below it too, under the LIDAR's range noise. [m]
  double refine_above_m = 0.01;
  int local_map_clouds = 8;          ///< how many previous clouds form the local map (accurate(): 24)
  /// LIDAR only (no motion prior): once the first cloud has left the local map, register
  /// it once more against the clouds that followed it, de-skewed with the velocity
  /// extrapolated back from the second and third chords, and re-express the trajectory
  /// and the local map so that the first pose keeps its place. The first two clouds share
  /// one velocity in their start-up fixed point (Odometry::add) while the cart's turn rate
  /// changes between them: on the sim street the first chord's yaw rate came out at twice
  /// the truth, a heading error the whole trajectory carried.
  bool reanchor_first_cloud = true;
  /// LIDAR only, 0 (off) or 4-8: once this many clouds have come, solve their trajectory
  /// again as one smooth curve from the first cloud's start (a cubic in time: it fits the
  /// sim street's first 3 s to 0.013 deg), every cloud registered against all the others
  /// at once, each point placed at the curve's pose at its own time; then replace their
  /// poses and local-map clouds with it. When it converges, the re-anchoring above is not
  /// needed and not done. Why: the chord between two start poses gives a tilt the rotation
  /// rate of 0.3-0.6 s before it, so each start pose is off in attitude, and the first
  /// pose's error turns the whole trajectory. With 4 clouds the first poses' attitude
  /// relative to the first came out 0.013-0.063 deg off on 4 sim streets, against
  /// 0.11-0.43 deg without. One solve, once: 0.15-0.36 s on 14 streets. On its own it
  /// leaves the anchored error as it was (14 streets: 0.075 against 0.077 m); with
  /// merged_local_map_m it lowers it (below).
  int start_up_clouds = 0;
  /// 0: the local map is the concatenation of its clouds, each with the covariances it
  /// came with (fast). > 0: the clouds are merged into one point per voxel of this size
  /// [m] and the GICP covariances computed anew from the merged points on every tilt, so
  /// that each comes from neighbours across clouds. Measured on 14 LIDAR-only 100 m sim
  /// streets (rgbdt_map_drift --seeds 14), mean anchored RMSE: 0.077 m concatenated,
  /// 0.069 m merged at 0.25 m, 0.056 m merged with start_up_clouds = 4. The covariances
  /// of the ~15k merged points cost 30-40 ms per tilt on one core (rgbdt_map_bench prints
  /// the whole tilt), over the real-time budget: off by default. Each is now computed the
  /// first time a correspondence uses it (~31 % of a window's fixed part on sim street
  /// seed 1 are ever used), which leaves the poses as they were. Tried: merging without
  /// new covariances (the clouds' own, averaged per voxel) 0.074 m (14 streets); merging
  /// every 2nd or 3rd tilt only, 0.079 / 0.060 m (7 streets).
  double merged_local_map_m = 0.0;
  /// LIDAR only, 0 (off) or 2 to local_map_clouds - 1: every window_interval_clouds tilts,
  /// solve the newest this many clouds' trajectory again as one smooth curve (a cubic in
  /// time, its start free), every cloud registered against the others and against the
  /// older clouds of the local map (held fixed), and replace their poses and local-map
  /// clouds with it. Each tilt's rotation rate then comes from the tilts around it, not from
  /// the chord before it. Measured with start_up_clouds = 4 and merged_local_map_m = 0.25 on
  /// the 14 streets, 3 clouds every 3rd tilt: mean anchored 0.036 m (RMS over the streets
  /// 0.044 m, 5 of 14 above 0.05 m, worst 0.091 m), aligned 0.008 m, against 0.056 / 0.017 m
  /// without. Without merged_local_map_m the windows make it worse (0.092 m). Time: see
  /// rgbdt_map_bench's --accurate row.
  int window_clouds = 0;
  /// A window every this many tilts (>= 1). The 14 streets, mean anchored / RMS / aligned:
  /// every tilt 0.038 / 0.043 / 0.0105 m, every 2nd 0.037 / 0.044 / 0.0086 m, every 3rd
  /// 0.036 / 0.044 / 0.0084 m: the error stays, the time goes to a third. With
  /// merged_local_map_m the map is merged anew at each window only; between windows the
  /// new clouds join the merged map with their own covariances (every 3rd: 0.0365 m merged
  /// anew on every tilt, 0.0362 m so).
  int window_interval_clouds = 3;
  /// The first window is solved once this many clouds have come. Windows from the 5th
  /// cloud on (their fixed part then only the first few clouds) measured worse: sim
  /// street seed 1, 0.069 m anchored against 0.028 m from the 13th.
  int window_start_clouds = 13;
  /// A diagnostic, with a motion prior (Odometry::set_motion_prior) only: every cloud is
  /// registered from, and joins the local map at, the prior's pose (relative to the first
  /// cloud) instead of the pose registered before. With the true motion as prior each
  /// registration then meets a map without accumulated error, so each returned pose's
  /// error is that registration's own bias on that tilt (rgbdt_map_drift's `map-at-truth`
  /// row). Measured so on the 14 sim streets: the mean pitch error per tilt differs with
  /// the sweep direction (docs/mapping.md, "The pitch bias").
  bool map_at_prior = false;
  double min_range_m = 0.5;          ///< points nearer (the cart itself) are ignored [m]
  double max_range_m = 40.0;         ///< farther points are ignored [m]
  std::string validate() const;

  /// rgbdt_mapper --accurate: the defaults with start_up_clouds = 4, merged_local_map_m =
  /// 0.25, window_clouds = 3 (every 3rd tilt from the 13th), local_map_clouds = 24 and
  /// settled_robust_scale2 = 0.1. On the 14 LIDAR-only 100 m sim streets of docs/mapping.md
  /// (rgbdt_map_drift --seeds 14), mean anchored RMSE 0.029 m (RMS over the streets 0.035 m,
  /// 1 of 14 above 0.05 m, worst 0.090 m), aligned 0.004 m, 79 ms per tilt against the
  /// default's 31 ms (thread CPU, same run); ~69 ms since the merged map's covariances are
  /// computed only for the points a correspondence uses (13 % less, poses identical). Without the settled scale 0.033 / 0.038 m, worst
  /// 0.074 m, aligned 0.007 m; with that and a local map of 8 clouds 0.036 / 0.044 m, 4 of
  /// 14 above 0.05 m, aligned 0.008 m, for ~20 % less time.
  static RegistrationOptions accurate();
};

struct RegistrationResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;
  double fitness_m2 = 0.0;  ///< mean squared correspondence distance [m^2]
  double time_ms = 0.0;
  std::size_t source_points = 0, target_points = 0;
  int iterations = 0;  ///< outer iterations of the last ICP run
};

using XyzCloud = pcl::PointCloud<pcl::PointXYZ>;

/// Voxel-grid downsampling (PCL VoxelGrid, centroid per voxel).
XyzCloud::Ptr downsample(const XyzCloud& cloud, double voxel_m);

/// One ICP run of `source` onto `target` from `guess` (both already downsampled).
RegistrationResult register_clouds(const XyzCloud::ConstPtr& source, const XyzCloud::ConstPtr& target,
                                   const Eigen::Isometry3d& guess, const RegistrationOptions& options = {});

/// Points of a tilt moved into the LIDAR frame at the cloud's start (point i is measured
/// at cloud[i].t after it) with a constant velocity: `motion_per_s` is the LIDAR's motion
/// over one second, T_start_(start+1s).
XyzCloud::Ptr deskew(const cloud::Cloud& cloud, const Eigen::Isometry3d& motion_per_s, double min_range_m = 0.0,
                     double max_range_m = 1e9);

/// Every point of a tilt in the world frame: point i at T_world_lidar(cloud_time_s + t_i) p_i.
std::vector<Eigen::Vector3f> points_in_world(const cloud::Cloud& cloud, double cloud_time_s,
                                             const Trajectory& trajectory);

/// Where the LIDAR was when each point of a tilt was measured, in the world frame: the
/// origins of the points' rays for OccupancyMapBuilder::insert_scan.
std::vector<Eigen::Vector3f> sensor_origins_in_world(const cloud::Cloud& cloud, double cloud_time_s,
                                                     const Trajectory& trajectory);

/// Scan-to-local-map odometry over successive tilts. Each tilt is downsampled once in the
/// sensor frame (voxel centroids keep their mean time, so de-skewing them with any velocity
/// is cheap and, to first order, equal to de-skewing every point); its GICP covariances
/// are computed once and, rotated into the world, kept with the cloud in the local map, so
/// the map's covariances are never recomputed.
class Odometry {
 public:
  explicit Odometry(const RegistrationOptions& options = {});
  ~Odometry();
  Odometry(Odometry&&) noexcept;
  Odometry& operator=(Odometry&&) noexcept;

  struct Step {
    Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();  ///< at cloud_time_s
    RegistrationResult registration;  ///< empty for the first cloud
    bool registered = false;
  };
  /// Adds the next tilt; cloud_time_s is the time of its first point, later than the
  /// previous cloud's. Throws std::invalid_argument otherwise.
  Step add(const cloud::Cloud& cloud, double cloud_time_s);

  /// Another estimate of the LIDAR's motion, T_frame_lidar(t) in any fixed frame: wheel
  /// odometry or an IMU moved to the LIDAR frame, or a previous run. Each later tilt is
  /// then de-skewed with the prior's motion within it, and registered from the prior's
  /// motion since the previous cloud instead of the constant-velocity prediction (and the
  /// first two clouds need no fixed point). Only relative motions over one tilt are used,
  /// so the prior's drift does not matter; its error over one tilt does.
  ///
  /// Why it matters: the first two tilts leave their common rotation rate open, a heading
  /// error the whole map carries, and a wrong de-skew costs accuracy on every tilt.
  /// bench/registration_drift.cpp, 7 LIDAR-only 100 m sim streets, mean anchored / aligned
  /// RMSE: LIDAR only 0.083 / 0.017 m (0.23 / 0.016 m without reanchor_first_cloud); a
  /// prior with a 0.02 deg + 1 cm random walk per tilt (an IMU) 0.058 / 0.016 m; the true
  /// motion 0.045 / 0.009 m. Call it before the first add().
  /// Throws std::invalid_argument on an empty trajectory, std::logic_error after add().
  void set_motion_prior(Trajectory prior);

  /// The LIDAR's rotation from a gyro (gyro_rotation_track): T_frame_lidar(t), of which
  /// only the rotation is used. Each later tilt is de-skewed with the gyro's rotation
  /// within it (and the constant-velocity translation), and registered from the rotation
  /// the gyro measured since the previous cloud (with the constant-velocity translation).
  /// A refined tilt is de-skewed again with the measured translation and the gyro's
  /// rotation. Only relative rotations over a tilt are used, and the gyro's bias is learnt
  /// as the tilts come: the mean rate by which the gyro's rotation between consecutive
  /// tilts differs from the registered rotation corrects it (gyro_correction_rad_s). The
  /// start-up, the windows and the re-anchoring run as without a prior. Ignored when a
  /// motion prior is set. Call it before the first add().
  /// Throws std::invalid_argument on an empty trajectory, std::logic_error after add().
  void set_rotation_prior(Trajectory rotations);
  /// The correction learnt for the gyro's bias (LIDAR axes; minus the bias) [rad/s], and
  /// from how many registered tilts.
  const Eigen::Vector3d& gyro_correction_rad_s() const { return gyro_correction_; }
  int gyro_correction_tilts() const { return gyro_correction_tilts_; }

  /// Poses at each cloud's start time; between them, pose_at interpolates. With
  /// RegistrationOptions::reanchor_first_cloud, the poses that add() returned for the
  /// first local_map_clouds clouds are re-expressed once (a rigid motion of all of them),
  /// when the next cloud is added: read the trajectory here, after the last add().
  const Trajectory& trajectory() const { return trajectory_; }

  /// What RegistrationOptions::reanchor_first_cloud did. Not attempted: the option is off,
  /// a motion prior is set, or too few clouds came. Attempted but not applied: the
  /// registration did not converge or moved the first cloud farther than
  /// max_correspondence_m, and the start was kept.
  struct Reanchoring {
    bool attempted = false;
    bool applied = false;
    /// New world from old: every pose after the first became correction * pose.
    Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
    RegistrationResult registration;  ///< the first cloud against the clouds that followed it
  };
  const Reanchoring& reanchoring() const { return reanchoring_; }
  /// What RegistrationOptions::start_up_clouds did. Attempted but not applied: the solve
  /// did not converge, or moved a pose farther than max_correspondence_m; the poses were
  /// kept, and the re-anchoring (if on) runs as without the start-up.
  struct StartUp {
    bool attempted = false;
    bool converged = false;
    bool applied = false;
    int iterations = 0;  ///< Gauss-Newton steps
    double time_ms = 0.0;
  };
  const StartUp& start_up() const { return start_up_; }
  /// What RegistrationOptions::window_clouds did: windows solved, of them not converged
  /// (their poses kept as registered), their steps, and the time they took.
  struct Window {
    int solves = 0;
    int not_converged = 0;
    int iterations = 0;  ///< Gauss-Newton steps, all windows
    double time_ms = 0.0;
  };
  const Window& window() const { return window_; }

  /// Heap memory held for the local map (points, covariances, search tree) [bytes].
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  RegistrationOptions options_;
  Trajectory trajectory_;
  Trajectory prior_;  ///< empty: LIDAR-only
  Trajectory rotation_prior_;  ///< empty: no gyro; only used while prior_ is empty
  Eigen::Vector3d gyro_correction_ = Eigen::Vector3d::Zero();
  int gyro_correction_tilts_ = 0;
  std::unique_ptr<Impl> impl_;
  Reanchoring reanchoring_;
  StartUp start_up_;
  Window window_;

  // add()'s steps, in the order it takes them (odometry.cpp).
  struct Tilt;  ///< one tilt on its way through add()
  void check_next_cloud(double cloud_time_s) const;
  void settle_robust_scale();
  Tilt prepare_tilt(const cloud::Cloud& cloud, double cloud_time_s) const;
  Eigen::Matrix3d gyro_rotation(double a_s, double b_s) const;
  void learn_gyro_correction(const Step& step);
  XyzCloud::Ptr deskew(const detail::TimedPoints& centroids, double time_s,
                       const Eigen::Isometry3d& velocity) const;
  void keep_for_start_up(const Tilt& tilt);
  Step register_tilt(Tilt& tilt);
  void register_second_cloud(Tilt& tilt, Step& step);
  void register_against_map(Tilt& tilt, Step& step);
  void join_local_map(Tilt& tilt, const Step& step);
  bool window_due() const;
  void rebuild_target_after_add();
  bool solves_start_up() const;
  bool start_up_due() const;
  void smooth_start_up();
  void refine_window();
  bool reanchoring_due() const;
  void reanchor_first_cloud();
};

}  // namespace rgbdt::rgbdt_map
