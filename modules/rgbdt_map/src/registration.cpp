#include "rgbdt/rgbdt_map/registration.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <pcl/filters/voxel_grid.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "registration_internal.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map {
namespace detail {

void configure(Icp& icp, const RegistrationOptions& options) {
  icp.setMaxCorrespondenceDistance(options.max_correspondence_m);
  icp.setMaximumIterations(options.max_iterations);
  // PCL's ICP compares the squared translation and the cosine of the rotation angle.
  icp.setTransformationEpsilon(options.translation_epsilon_m * options.translation_epsilon_m);
  icp.setTransformationRotationEpsilon(std::cos(options.rotation_epsilon_rad));
}

void configure(Gicp& gicp, const RegistrationOptions& options) {
  gicp.setMaxCorrespondenceDistance(options.max_correspondence_m);
  gicp.setMaximumIterations(options.max_iterations);
  // GICP's own test: largest change of a translation component / rotation matrix element.
  gicp.setTransformationEpsilon(options.translation_epsilon_m);
  gicp.setRotationEpsilon(options.rotation_epsilon_rad);
  gicp.setCorrespondenceRandomness(options.covariance_neighbours);
  gicp.setMaximumOptimizerIterations(options.optimizer_iterations);
}

Eigen::Isometry3d to_isometry(const Eigen::Matrix4f& M_f) {
  const Eigen::Matrix4d M = M_f.cast<double>();
  // Re-orthonormalise the float rotation before it becomes an Isometry.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::Quaterniond(Eigen::Matrix3d(M.block<3, 3>(0, 0))).normalized().toRotationMatrix();
  T.translation() = M.block<3, 1>(0, 3);
  return T;
}

TimedPoints sensor_voxels(const cloud::Cloud& cloud, double voxel_m, double min_range_m,
                          double max_range_m) {
  // PCL's VoxelGrid averages the fields it knows (x y z intensity ...), not `t`: carry the
  // time in `intensity`.
  auto timed = std::make_shared<pcl::PointCloud<pcl::PointXYZI>>();
  timed->reserve(cloud.size());
  for (const auto& p : cloud) {
    const float range = p.getVector3fMap().norm();
    if (!std::isfinite(range) || range < min_range_m || range > max_range_m) continue;
    pcl::PointXYZI q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    q.intensity = p.t;
    timed->push_back(q);
  }
  pcl::PointCloud<pcl::PointXYZI> centroids;
  pcl::VoxelGrid<pcl::PointXYZI> grid;
  grid.setInputCloud(timed);
  const float leaf = static_cast<float>(voxel_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.setDownsampleAllData(true);  // intensity too: the voxel's mean time
  grid.filter(centroids);
  TimedPoints out;
  out.points.reserve(centroids.size());
  out.t_s.reserve(centroids.size());
  for (const auto& p : centroids) {
    out.points.emplace_back(p.x, p.y, p.z);
    out.t_s.push_back(p.intensity);
  }
  return out;
}

XyzCloud::Ptr deskew_points(const TimedPoints& in, const Eigen::Isometry3d& motion_per_s) {
  const core::Vector6d twist = core::to_vector6(motion_per_s);
  return deskew_points(in, [&twist](double tau_s) { return core::from_vector6(twist * tau_s); });
}

}  // namespace detail

using detail::align;
using detail::Clock;
using detail::configure;
using detail::Counted;
using detail::CovarianceGicp;
using detail::Gicp;
using detail::Icp;
using detail::MapTree;
using detail::ms_since;
using detail::robust_gicp;
using detail::TargetCovariances;

const char* to_string(IcpBackend backend) {
  switch (backend) {
    case IcpBackend::kRobust:
      return "rgicp";
    case IcpBackend::kGeneralized:
      return "gicp";
    case IcpBackend::kPointToPoint:
      return "icp";
  }
  return "?";
}

IcpBackend icp_backend_from_string(const std::string& name) {
  if (name == "rgicp") return IcpBackend::kRobust;
  if (name == "gicp") return IcpBackend::kGeneralized;
  if (name == "icp") return IcpBackend::kPointToPoint;
  throw std::invalid_argument("ICP backend '" + name +
                              "' unknown, expected 'rgicp', 'gicp' or 'icp'");
}

std::string RegistrationOptions::validate() const {
  std::ostringstream os;
  if (!(source_voxel_m > 0.0)) os << "source_voxel_m = " << source_voxel_m << ", expected > 0; ";
  if (!(max_correspondence_m > 0.0)) {
    os << "max_correspondence_m = " << max_correspondence_m << ", expected > 0; ";
  }
  if (max_iterations < 1) os << "max_iterations = " << max_iterations << ", expected >= 1; ";
  if (!(translation_epsilon_m > 0.0)) {
    os << "translation_epsilon_m = " << translation_epsilon_m << ", expected > 0; ";
  }
  if (!(rotation_epsilon_rad > 0.0)) {
    os << "rotation_epsilon_rad = " << rotation_epsilon_rad << ", expected > 0; ";
  }
  if (!(robust_scale2 > 0.0)) os << "robust_scale2 = " << robust_scale2 << ", expected > 0; ";
  if (!(settled_robust_scale2 >= 0.0)) {
    os << "settled_robust_scale2 = " << settled_robust_scale2 << ", expected 0 (off) or > 0; ";
  }
  if (settled_from_cloud < 2) {
    os << "settled_from_cloud = " << settled_from_cloud << ", expected >= 2; ";
  }
  if (window_clouds != 0 && (window_clouds < 2 || window_clouds >= local_map_clouds)) {
    os << "window_clouds = " << window_clouds
       << ", expected 0 (off) or 2 to local_map_clouds - 1 = " << local_map_clouds - 1 << "; ";
  }
  if (window_interval_clouds < 1) {
    os << "window_interval_clouds = " << window_interval_clouds << ", expected >= 1; ";
  }
  if (window_clouds != 0 && window_start_clouds <= window_clouds) {
    os << "window_start_clouds = " << window_start_clouds
       << ", expected > window_clouds = " << window_clouds << "; ";
  }
  if (start_up_clouds != 0 && (start_up_clouds < 4 || start_up_clouds > 8)) {
    os << "start_up_clouds = " << start_up_clouds << ", expected 0 (off) or 4-8; ";
  }
  if (!(merged_local_map_m >= 0.0 && merged_local_map_m < 10.0)) {
    os << "merged_local_map_m = " << merged_local_map_m
       << ", expected 0 (off) or a voxel size in m; ";
  }
  if (covariance_neighbours < 3) {
    os << "covariance_neighbours = " << covariance_neighbours << ", expected >= 3; ";
  }
  if (optimizer_iterations < 1) {
    os << "optimizer_iterations = " << optimizer_iterations << ", expected >= 1; ";
  }
  if (!(refine_above_m >= 0.0)) os << "refine_above_m = " << refine_above_m << ", expected >= 0; ";
  if (local_map_clouds < 1) os << "local_map_clouds = " << local_map_clouds << ", expected >= 1; ";
  if (!(min_range_m >= 0.0 && max_range_m > min_range_m)) {
    os << "range [" << min_range_m << ", " << max_range_m << "] m, expected 0 <= min < max; ";
  }
  return os.str();
}

RegistrationOptions RegistrationOptions::accurate() {
  RegistrationOptions options;
  options.start_up_clouds = 4;
  options.merged_local_map_m = 0.25;
  options.window_clouds = 3;
  options.local_map_clouds = 24;
  options.settled_robust_scale2 = 0.1;
  return options;
}

XyzCloud::Ptr downsample(const XyzCloud& cloud, double voxel_m) {
  auto out = std::make_shared<XyzCloud>();
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(std::shared_ptr<const XyzCloud>(&cloud, [](const XyzCloud*) {}));
  const float leaf = static_cast<float>(voxel_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(*out);
  return out;
}

RegistrationResult register_clouds(const XyzCloud::ConstPtr& source,
                                   const XyzCloud::ConstPtr& target, const Eigen::Isometry3d& guess,
                                   const RegistrationOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("RegistrationOptions: " + why);
  }
  const std::size_t min_points = std::max<std::size_t>(10, options.covariance_neighbours);
  if (!source || !target || source->size() < min_points || target->size() < min_points) {
    throw std::invalid_argument("register_clouds: need at least " + std::to_string(min_points) +
                                " source and target points, got " +
                                std::to_string(source ? source->size() : 0) + " and " +
                                std::to_string(target ? target->size() : 0));
  }
  const auto start = Clock::now();
  RegistrationResult result;
  result.target_points = target->size();
  auto run = [&](auto& icp) {
    configure(icp, options);
    icp.setInputTarget(target);
    icp.setInputSource(source);
    align(icp, source, guess, result);
    result.fitness_m2 = icp.getFitnessScore(options.max_correspondence_m);
  };
  if (options.backend == IcpBackend::kRobust) {
    CovarianceGicp estimator;
    configure(estimator, options);
    MapTree tree;
    tree.setInputCloud(target);
    const RegistrationResult r =
        robust_gicp(*source, *estimator.covariances_of(source), *target, tree,
                    TargetCovariances(estimator.covariances_of(target, &tree)), guess, options);
    result.T_target_source = r.T_target_source;
    result.converged = r.converged;
    result.iterations = r.iterations;
    result.fitness_m2 = r.fitness_m2;
    result.source_points = source->size();
  } else if (options.backend == IcpBackend::kGeneralized) {
    Counted<Gicp> gicp;
    run(gicp);
  } else {
    Counted<Icp> icp;
    run(icp);
  }
  result.time_ms = ms_since(start);
  return result;
}

XyzCloud::Ptr deskew(const cloud::Cloud& cloud, const Eigen::Isometry3d& motion_per_s,
                     double min_range_m, double max_range_m) {
  const core::Vector6d twist = core::to_vector6(motion_per_s);
  const bool moving = twist.norm() > 1e-12;
  auto out = std::make_shared<XyzCloud>();
  out->reserve(cloud.size());
  // Points of one scan line share nearly the same time: cache the pose per 1 ms.
  long long cached_bin = std::numeric_limits<long long>::min();
  Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
  for (const auto& p : cloud) {
    const Eigen::Vector3f q(p.x, p.y, p.z);
    const float range = q.norm();
    if (!std::isfinite(range) || range < min_range_m || range > max_range_m) continue;
    if (moving) {
      const long long bin = std::llround(p.t * 1000.0);
      if (bin != cached_bin) {
        T = core::from_vector6(twist * (bin * 1e-3)).cast<float>();
        cached_bin = bin;
      }
    }
    const Eigen::Vector3f r = T * q;
    out->push_back(pcl::PointXYZ(r.x(), r.y(), r.z()));
  }
  return out;
}

std::vector<Eigen::Vector3f> points_in_world(const cloud::Cloud& cloud, double cloud_time_s,
                                             const Trajectory& trajectory) {
  std::vector<Eigen::Vector3f> out(cloud.size());
  long long cached_bin = std::numeric_limits<long long>::min();
  Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const long long bin = std::llround(cloud[i].t * 2000.0);  // 0.5 ms
    if (bin != cached_bin) {
      T = trajectory.pose_at(cloud_time_s + bin * 5e-4).cast<float>();
      cached_bin = bin;
    }
    out[i] = T * Eigen::Vector3f(cloud[i].x, cloud[i].y, cloud[i].z);
  }
  return out;
}

std::vector<Eigen::Vector3f> sensor_origins_in_world(const cloud::Cloud& cloud, double cloud_time_s,
                                                     const Trajectory& trajectory) {
  std::vector<Eigen::Vector3f> out(cloud.size());
  long long cached_bin = std::numeric_limits<long long>::min();
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const long long bin = std::llround(cloud[i].t * 2000.0);  // 0.5 ms, as points_in_world
    if (bin != cached_bin) {
      origin = trajectory.pose_at(cloud_time_s + bin * 5e-4).translation().cast<float>();
      cached_bin = bin;
    }
    out[i] = origin;
  }
  return out;
}

}  // namespace rgbdt::rgbdt_map
