#include "rgbdt/rgbdt_map/registration.hpp"

#include <pcl/filters/voxel_grid.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>

#include <pcl/common/transforms.h>

#include <chrono>
#include <limits>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map {
namespace {
constexpr int kInitIterations = 6;  ///< fixed-point iterations for the second cloud (converge in 3-4)
}  // namespace

const char* to_string(IcpBackend backend) {
  return backend == IcpBackend::kGeneralized ? "gicp" : "icp";
}

IcpBackend icp_backend_from_string(const std::string& name) {
  if (name == "gicp") return IcpBackend::kGeneralized;
  if (name == "icp") return IcpBackend::kPointToPoint;
  throw std::invalid_argument("ICP backend '" + name + "' unknown, expected 'gicp' or 'icp'");
}

std::string RegistrationOptions::validate() const {
  std::ostringstream os;
  if (!(source_voxel_m > 0.0)) os << "source_voxel_m = " << source_voxel_m << ", expected > 0; ";
  if (!(map_voxel_m > 0.0)) os << "map_voxel_m = " << map_voxel_m << ", expected > 0; ";
  if (!(max_correspondence_m > 0.0)) os << "max_correspondence_m = " << max_correspondence_m << ", expected > 0; ";
  if (max_iterations < 1) os << "max_iterations = " << max_iterations << ", expected >= 1; ";
  if (local_map_clouds < 1) os << "local_map_clouds = " << local_map_clouds << ", expected >= 1; ";
  if (!(min_range_m >= 0.0 && max_range_m > min_range_m)) {
    os << "range [" << min_range_m << ", " << max_range_m << "] m, expected 0 <= min < max; ";
  }
  return os.str();
}

XyzCloud::Ptr downsample(const XyzCloud& cloud, double voxel_m) {
  auto out = std::make_shared<XyzCloud>();
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(std::make_shared<XyzCloud>(cloud));
  const float leaf = static_cast<float>(voxel_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(*out);
  return out;
}

RegistrationResult register_clouds(const XyzCloud::ConstPtr& source, const XyzCloud::ConstPtr& target,
                                   const Eigen::Isometry3d& guess, const RegistrationOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("RegistrationOptions: " + why);
  }
  if (!source || !target || source->size() < 10 || target->size() < 10) {
    throw std::invalid_argument("register_clouds: need at least 10 source and target points, got " +
                                std::to_string(source ? source->size() : 0) + " and " +
                                std::to_string(target ? target->size() : 0));
  }
  const auto start = std::chrono::steady_clock::now();
  RegistrationResult result;
  result.source_points = source->size();
  result.target_points = target->size();
  XyzCloud aligned;
  const Eigen::Matrix4f guess_f = guess.matrix().cast<float>();
  auto run = [&](auto& icp) {
    icp.setInputSource(source);
    icp.setInputTarget(target);
    icp.setMaxCorrespondenceDistance(options.max_correspondence_m);
    icp.setMaximumIterations(options.max_iterations);
    icp.setTransformationEpsilon(options.transformation_epsilon);
    icp.align(aligned, guess_f);
    result.converged = icp.hasConverged();
    result.fitness_m2 = icp.getFitnessScore(options.max_correspondence_m);
    Eigen::Matrix4d M = icp.getFinalTransformation().template cast<double>();
    // Re-orthonormalise the float rotation before it becomes an Isometry.
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(Eigen::Matrix3d(M.block<3, 3>(0, 0))).normalized().toRotationMatrix();
    T.translation() = M.block<3, 1>(0, 3);
    result.T_target_source = T;
  };
  if (options.backend == IcpBackend::kGeneralized) {
    pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
    run(gicp);
  } else {
    pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> icp;
    run(icp);
  }
  result.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

XyzCloud::Ptr deskew(const cloud::Cloud& cloud, const Eigen::Isometry3d& motion_per_s, double min_range_m,
                     double max_range_m) {
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

Odometry::Odometry(const RegistrationOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("RegistrationOptions: " + why);
  }
}

void Odometry::rebuild_map() {
  XyzCloud all;
  for (const auto& c : recent_world_) all += *c;
  local_map_ = downsample(all, options_.map_voxel_m);
}

Odometry::Step Odometry::add(const cloud::Cloud& cloud, double cloud_time_s) {
  const auto& poses = trajectory_.poses();
  if (!poses.empty() && !(cloud_time_s > poses.back().time_s)) {
    throw std::invalid_argument("Odometry::add: cloud time " + std::to_string(cloud_time_s) +
                                " s is not after the previous cloud's " + std::to_string(poses.back().time_s) + " s");
  }
  auto velocity_between = [](const TimedPose& a, const TimedPose& b) {
    return core::from_vector6(core::to_vector6(a.T_world_lidar.inverse() * b.T_world_lidar) / (b.time_s - a.time_s));
  };
  // Constant-velocity prediction from the last two poses.
  Eigen::Isometry3d predicted = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d motion_per_s = Eigen::Isometry3d::Identity();
  if (poses.size() >= 2) {
    const TimedPose& a = poses[poses.size() - 2];
    const TimedPose& b = poses.back();
    motion_per_s = velocity_between(a, b);
    predicted = scale_motion(a.T_world_lidar, b.T_world_lidar, (cloud_time_s - a.time_s) / (b.time_s - a.time_s));
  } else if (poses.size() == 1) {
    predicted = poses.back().T_world_lidar;
  }
  auto prepare = [&](const cloud::Cloud& c, const Eigen::Isometry3d& velocity) {
    return downsample(*deskew(c, velocity, options_.min_range_m, options_.max_range_m), options_.source_voxel_m);
  };
  XyzCloud::Ptr source = prepare(cloud, motion_per_s);

  Step step;
  step.T_world_lidar = predicted;
  if (poses.size() == 1 && first_cloud_) {
    // Second cloud: no velocity yet, and the first cloud in the map is skewed by the very
    // motion being estimated. Iterate to the fixed point where the velocity that de-skews
    // both clouds is the one their registration measures.
    const TimedPose first = poses.front();
    Eigen::Isometry3d velocity = Eigen::Isometry3d::Identity();
    for (int iteration = 0; iteration < kInitIterations; ++iteration) {
      auto map = std::make_shared<XyzCloud>();
      pcl::transformPointCloud(*prepare(*first_cloud_, velocity), *map, first.T_world_lidar.matrix().cast<float>());
      source = prepare(cloud, velocity);
      const RegistrationResult r = register_clouds(source, map, step.T_world_lidar, options_);
      const double change = core::translation_error_m(r.T_target_source, step.T_world_lidar);
      step.registration.time_ms += r.time_ms;
      step.registration.T_target_source = r.T_target_source;
      step.registration.converged = r.converged;
      step.registration.fitness_m2 = r.fitness_m2;
      step.registration.source_points = r.source_points;
      step.registration.target_points = r.target_points;
      step.T_world_lidar = r.T_target_source;
      velocity = velocity_between(first, {cloud_time_s, step.T_world_lidar});
      if (iteration > 0 && change < 1e-3) break;
    }
    step.registered = true;
    recent_world_.front() = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*prepare(*first_cloud_, velocity), *recent_world_.front(),
                             first.T_world_lidar.matrix().cast<float>());
    first_cloud_.reset();
  } else if (local_map_ && !local_map_->empty()) {
    step.registration = register_clouds(source, local_map_, predicted, options_);
    step.registered = true;
    step.T_world_lidar = step.registration.T_target_source;
    // The registration measured this cloud's motion since the previous one: de-skew with
    // that velocity and refine once (the prediction is off whenever the cart accelerates).
    const Eigen::Isometry3d measured = velocity_between(poses.back(), {cloud_time_s, step.T_world_lidar});
    source = prepare(cloud, measured);
    const RegistrationResult refined = register_clouds(source, local_map_, step.T_world_lidar, options_);
    step.registration.T_target_source = refined.T_target_source;
    step.registration.converged = refined.converged;
    step.registration.fitness_m2 = refined.fitness_m2;
    step.registration.time_ms += refined.time_ms;
    step.T_world_lidar = refined.T_target_source;
  }
  trajectory_.push_back({cloud_time_s, step.T_world_lidar});

  auto world = std::make_shared<XyzCloud>();
  pcl::transformPointCloud(*source, *world, step.T_world_lidar.matrix().cast<float>());
  recent_world_.push_back(world);
  if (poses.size() == 1) first_cloud_ = std::make_shared<cloud::Cloud>(cloud);
  while (static_cast<int>(recent_world_.size()) > options_.local_map_clouds) recent_world_.pop_front();
  rebuild_map();
  return step;
}

}  // namespace rgbdt::rgbdt_map
