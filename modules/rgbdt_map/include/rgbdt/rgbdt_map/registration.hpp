#pragma once
/// \file
/// Registration of successive tilt clouds into one trajectory (paper Sec. 5: "our 3D
/// mapping pipeline (which is implemented using the Iterative Closest Point [4]
/// algorithm)"). Each new cloud is de-skewed with the constant-velocity model (a tilt
/// lasts 600 ms, during which the cart moves), registered against a local map made of the
/// previous clouds (so also against its predecessor), starting from the constant-velocity
/// prediction.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <deque>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"

namespace rgbdt::rgbdt_map {

enum class IcpBackend {
  kGeneralized,   ///< pcl::GeneralizedIterativeClosestPoint (plane-to-plane)
  kPointToPoint,  ///< pcl::IterativeClosestPoint
};
const char* to_string(IcpBackend backend);
/// "gicp" or "icp"; throws std::invalid_argument naming the value otherwise.
IcpBackend icp_backend_from_string(const std::string& name);

struct RegistrationOptions {
  /// GICP: chosen on the benchmark (bench/rgbdt_map_bench.cpp): on the same clouds it
  /// converges in fewer iterations and is more accurate than point-to-point ICP.
  IcpBackend backend = IcpBackend::kGeneralized;
  double source_voxel_m = 0.25;      ///< the new cloud is voxel-downsampled to this [m]
  double map_voxel_m = 0.25;         ///< the local map is voxel-downsampled to this [m]
  double max_correspondence_m = 1.0;  ///< correspondence gate; > expected prediction error [m]
  int max_iterations = 30;
  double transformation_epsilon = 1e-6;  ///< convergence on the update's squared size
  int local_map_clouds = 8;          ///< how many previous clouds form the local map
  double min_range_m = 0.5;          ///< points nearer (the cart itself) are ignored [m]
  double max_range_m = 40.0;         ///< farther points are ignored [m]
  std::string validate() const;
};

struct RegistrationResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool converged = false;
  double fitness_m2 = 0.0;  ///< mean squared correspondence distance [m^2]
  double time_ms = 0.0;
  std::size_t source_points = 0, target_points = 0;
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

/// Scan-to-local-map odometry over successive tilts.
class Odometry {
 public:
  explicit Odometry(const RegistrationOptions& options = {});

  struct Step {
    Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();  ///< at cloud_time_s
    RegistrationResult registration;  ///< empty for the first cloud
    bool registered = false;
  };
  /// Adds the next tilt; cloud_time_s is the time of its first point, later than the
  /// previous cloud's. Throws std::invalid_argument otherwise.
  Step add(const cloud::Cloud& cloud, double cloud_time_s);

  /// Poses at each cloud's start time; between them, pose_at interpolates.
  const Trajectory& trajectory() const { return trajectory_; }

 private:
  void rebuild_map();

  RegistrationOptions options_;
  Trajectory trajectory_;
  std::deque<XyzCloud::Ptr> recent_world_;
  XyzCloud::Ptr local_map_;
  std::shared_ptr<cloud::Cloud> first_cloud_;  ///< kept until a velocity is known to de-skew it
};

}  // namespace rgbdt::rgbdt_map
