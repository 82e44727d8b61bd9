#include "rgbdt/rgbdt_map/registration.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <pcl/common/transforms.h>

#include <algorithm>
#include <deque>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "registration_internal.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map {

using detail::align;
using detail::Clock;
using detail::configure;
using detail::Counted;
using detail::CovarianceGicp;
using detail::Covariances;
using detail::curve_vector;
using detail::CurveCloud;
using detail::CurveResult;
using detail::deskew_points;
using detail::fit_curve;
using detail::FixedMap;
using detail::Icp;
using detail::MapTree;
using detail::ms_since;
using detail::NearestKept;
using detail::robust_gicp;
using detail::sensor_voxels;
using detail::solve_curve;
using detail::TargetCovariances;
using detail::TimedPoints;

namespace {

constexpr int kInitIterations =
    6;  ///< fixed-point iterations for the second cloud (converge in 3-4)

/// The constant twist that moves pose a to pose b in their time apart (per second, in a's frame).
core::Vector6d twist_between(const TimedPose& a, const TimedPose& b) {
  return core::to_vector6(a.T_world_lidar.inverse() * b.T_world_lidar) / (b.time_s - a.time_s);
}

/// The constant velocity that moves pose a to pose b in their time apart, over one second.
Eigen::Isometry3d velocity_between(const TimedPose& a, const TimedPose& b) {
  return core::from_vector6(twist_between(a, b));
}

/// The constant rate that, applied on the right over dt, turns rotation `from` into `to`.
Eigen::Vector3d rotation_rate_between(const Eigen::Matrix3d& from, const Eigen::Matrix3d& to,
                                      double dt) {
  const Eigen::AngleAxisd residual(from.transpose() * to);
  return residual.axis() * (residual.angle() / dt);
}

}  // namespace

/// The local map: the last clouds in the world frame with their GICP covariances, and
/// the aligners holding it as their target (its search tree is built once per tilt and
/// serves both registrations of the tilt).
struct Odometry::Impl {
  struct MapCloud {
    XyzCloud::Ptr points_world;
    std::shared_ptr<Covariances> covariances_world;  ///< null for point-to-point ICP
    TimedPoints sensor;  ///< the centroids in the sensor frame, while the first cloud awaits its
                         ///< re-anchoring
    TimedPoints
        centroids;  ///< the centroids in the sensor frame, for RegistrationOptions::window_clouds
    double start_s = 0.0;  ///< the cloud's time, with `centroids`
    double end_s = 0.0;    ///< its last centroid's time, with `centroids`
    Eigen::Isometry3d T_world_end =
        Eigen::Isometry3d::Identity();  ///< the pose it is placed with at end_s
    double time_s = 0.0;
    long serial = 0;
  };
  std::deque<MapCloud> recent;
  XyzCloud::Ptr map;
  CovarianceGicp gicp;
  Counted<Icp> icp;
  std::shared_ptr<MapTree> map_tree =
      std::make_shared<MapTree>();    ///< kRobust: search tree of `map`
  TargetCovariances map_covariances;  ///< kRobust: those of `map`
  TimedPoints
      first_cloud;  ///< the first tilt's centroids, until a velocity is known to de-skew them
  bool have_first = false;
  TimedPoints anchor;                ///< the first tilt's centroids, until reanchor_first_cloud
  std::vector<CurveCloud> start_up;  ///< the first clouds' centroids, until smooth_start_up

  /// The local map as last merged (RegistrationOptions::merged_local_map_m, kRobust).
  XyzCloud::Ptr merged_points;
  TargetCovariances merged_covariances;
  long merged_serial = -1;  ///< the newest cloud in it
  long serial = 0;          ///< the clouds added so far
  /// RegistrationOptions::robust_scale2 as given, before settled_robust_scale2 replaces it.
  double loose_robust_scale2 = 1.0;

  /// Rebuilds the target from `recent`: concatenation, no new covariances; the search
  /// tree is rebuilt once, here or on the next alignment. Merged (merge_m > 0): one point
  /// per voxel over all the clouds, covariances from neighbours across them. append: the
  /// last merged map, with the clouds added since joining it as they are (between windows).
  void rebuild_target(IcpBackend backend, double merge_m, bool append = false) {
    if (append && merged_points && backend == IcpBackend::kRobust) {
      map = std::make_shared<XyzCloud>(*merged_points);
      Covariances appended;
      for (const auto& c : recent) {
        if (c.serial <= merged_serial) continue;
        *map += *c.points_world;
        appended.insert(appended.end(), c.covariances_world->begin(), c.covariances_world->end());
      }
      map_tree =
          std::make_shared<MapTree>();  // a new one: the merged part's lazy covariances keep theirs
      map_tree->setInputCloud(map);
      map_covariances = merged_covariances.followed_by(appended);
      return;
    }
    const bool generalized = backend != IcpBackend::kPointToPoint;
    map = std::make_shared<XyzCloud>();
    auto covariances = std::make_shared<Covariances>();
    for (const auto& c : recent) {
      *map += *c.points_world;
      if (generalized) {
        covariances->insert(covariances->end(), c.covariances_world->begin(),
                            c.covariances_world->end());
      }
    }
    const bool merge = merge_m > 0.0 && generalized && recent.size() >= 2;
    if (merge) map = downsample(*map, merge_m);
    if (backend == IcpBackend::kRobust) {
      map_tree = std::make_shared<MapTree>();  // a new one: lazy covariances keep the tree they
                                               // were made with
      map_tree->setInputCloud(map);
      // The tree serves the searches and a merged map's covariances.
      map_covariances = merge ? TargetCovariances(map, map_tree, gicp.getCorrespondenceRandomness())
                              : TargetCovariances(covariances);
      if (merge) {
        merged_points = map;
        merged_covariances = map_covariances;
        merged_serial = recent.back().serial;
      }
    } else if (generalized) {
      if (merge) covariances = gicp.covariances_of(map);
      gicp.setInputTarget(map);
      gicp.setTargetCovariances(covariances);  // after setInputTarget, which resets them
    } else {
      icp.setInputTarget(map);
    }
  }
};

Odometry::Odometry(const RegistrationOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("RegistrationOptions: " + why);
  }
  configure(impl_->gicp, options_);
  configure(impl_->icp, options_);
  impl_->loose_robust_scale2 = options_.robust_scale2;
}

Odometry::~Odometry() = default;
Odometry::Odometry(Odometry&&) noexcept = default;
Odometry& Odometry::operator=(Odometry&&) noexcept = default;

std::size_t Odometry::memory_bytes() const {
  std::size_t bytes = 0;
  for (const auto& c : impl_->recent) {
    bytes += c.points_world->size() * sizeof(pcl::PointXYZ);
    if (c.covariances_world) bytes += c.covariances_world->size() * sizeof(Eigen::Matrix3d);
  }
  if (impl_->map) bytes += impl_->map->size() * (sizeof(pcl::PointXYZ) + sizeof(Eigen::Matrix3d));
  if (impl_->merged_points && impl_->merged_points != impl_->map) {
    bytes += impl_->merged_points->size() * (sizeof(pcl::PointXYZ) + sizeof(Eigen::Matrix3d));
  }
  std::size_t timed_points = impl_->first_cloud.points.size() + impl_->anchor.points.size();
  for (const auto& c : impl_->recent) {
    timed_points += c.sensor.points.size() + c.centroids.points.size();
  }
  for (const auto& c : impl_->start_up) timed_points += c.sensor.points.size();
  bytes += timed_points * (sizeof(Eigen::Vector3f) + sizeof(float));
  return bytes;
}

void Odometry::set_motion_prior(Trajectory prior) {
  if (prior.empty()) throw std::invalid_argument("Odometry::set_motion_prior: empty trajectory");
  if (!trajectory_.empty()) {
    throw std::logic_error("Odometry::set_motion_prior: " + std::to_string(trajectory_.size()) +
                           " clouds already added; set the prior before the first");
  }
  prior_ = std::move(prior);
}

void Odometry::set_rotation_prior(Trajectory rotations) {
  if (rotations.empty()) {
    throw std::invalid_argument("Odometry::set_rotation_prior: empty trajectory");
  }
  if (!trajectory_.empty()) {
    throw std::logic_error("Odometry::set_rotation_prior: " + std::to_string(trajectory_.size()) +
                           " clouds already added; set the prior before the first");
  }
  rotation_prior_ = std::move(rotations);
}

/// The gyro's rotation from time a to time b, in the LIDAR frame at a, with the learnt
/// correction of its bias.
Eigen::Matrix3d Odometry::gyro_rotation(double a_s, double b_s) const {
  const Eigen::Vector3d correction = gyro_correction_ * (b_s - a_s);
  const Eigen::Matrix3d raw =
      rotation_prior_.pose_at(a_s).linear().transpose() * rotation_prior_.pose_at(b_s).linear();
  if (correction.norm() == 0.0) return raw;
  return raw * Eigen::AngleAxisd(correction.norm(), correction.normalized()).toRotationMatrix();
}

/// The gyro's bias from this registered tilt: the rate that turns the gyro's rotation since
/// the previous tilt into the registered one, averaged over the tilts so far (over the last
/// ~50 once there are more, so a slowly drifting bias is followed).
void Odometry::learn_gyro_correction(const Step& step) {
  const auto& poses = trajectory_.poses();
  if (rotation_prior_.empty() || !prior_.empty() || poses.size() < 2 || !step.registered ||
      !step.registration.converged) {
    return;
  }
  const TimedPose& a = poses[poses.size() - 2];
  const TimedPose& b = poses.back();
  const double dt = b.time_s - a.time_s;
  const Eigen::Matrix3d gyro =
      rotation_prior_.pose_at(a.time_s).linear().transpose() * rotation_prior_.pose_at(b.time_s).linear();
  const Eigen::Vector3d rate = rotation_rate_between(
      gyro, a.T_world_lidar.linear().transpose() * b.T_world_lidar.linear(), dt);
  ++gyro_correction_tilts_;
  const double weight = 1.0 / std::min(gyro_correction_tilts_, 50);
  gyro_correction_ += weight * (rate - gyro_correction_);
}

/// One tilt on its way through add().
struct Odometry::Tilt {
  double time_s = 0.0;    ///< its first point's
  TimedPoints centroids;  ///< in the sensor frame
  /// Its pose as predicted: from the constant velocity, or from the motion prior.
  Eigen::Isometry3d predicted = Eigen::Isometry3d::Identity();
  XyzCloud::Ptr source;  ///< the centroids de-skewed, as registered
  /// The velocity `source` is de-skewed with (no prior).
  Eigen::Isometry3d deskewed_by = Eigen::Isometry3d::Identity();
  std::shared_ptr<Covariances> source_covariances;  ///< `source`'s, once computed
};

/// Centroids of the tilt that started at `time_s` de-skewed with `velocity` (per second,
/// constant over the tilt), its rotation taken from the gyro when there is one.
XyzCloud::Ptr Odometry::deskew(const TimedPoints& centroids, double time_s,
                               const Eigen::Isometry3d& velocity) const {
  if (rotation_prior_.empty() || !prior_.empty()) return deskew_points(centroids, velocity);
  const core::Vector6d twist = core::to_vector6(velocity);
  return deskew_points(centroids, [&](double tau_s) {
    Eigen::Isometry3d T = core::from_vector6(twist * tau_s);
    T.linear() = gyro_rotation(time_s, time_s + tau_s);
    return T;
  });
}

Odometry::Step Odometry::add(const cloud::Cloud& cloud, double cloud_time_s) {
  check_next_cloud(cloud_time_s);
  const auto start = Clock::now();
  settle_robust_scale();
  Tilt tilt = prepare_tilt(cloud, cloud_time_s);
  keep_for_start_up(tilt);
  Step step = register_tilt(tilt);
  trajectory_.push_back({cloud_time_s, step.T_world_lidar});
  join_local_map(tilt, step);
  const bool window = window_due();
  // The window rebuilds the target itself, from the clouds it moved.
  if (!window) rebuild_target_after_add();
  if (start_up_due()) smooth_start_up();
  if (window) refine_window();
  if (reanchoring_due()) reanchor_first_cloud();
  learn_gyro_correction(step);
  step.registration.time_ms = ms_since(start);
  return step;
}

/// Throws unless a cloud at cloud_time_s may come next.
void Odometry::check_next_cloud(double cloud_time_s) const {
  const auto& poses = trajectory_.poses();
  if (!poses.empty() && !(cloud_time_s > poses.back().time_s)) {
    throw std::invalid_argument("Odometry::add: cloud time " + std::to_string(cloud_time_s) +
                                " s is not after the previous cloud's " +
                                std::to_string(poses.back().time_s) + " s");
  }
  if (options_.map_at_prior && prior_.empty()) {
    throw std::logic_error(
        "Odometry::add: RegistrationOptions::map_at_prior needs a motion prior (set_motion_prior)");
  }
}

/// RegistrationOptions::settled_robust_scale2 from the settled_from_cloud-th cloud on.
void Odometry::settle_robust_scale() {
  // From here on every registration, window and re-anchoring uses the settled scale.
  if (options_.settled_robust_scale2 > 0.0 &&
      static_cast<int>(trajectory_.size()) == options_.settled_from_cloud) {
    options_.robust_scale2 = options_.settled_robust_scale2;
  }
}

/// The tilt's centroids, its predicted pose, and its centroids de-skewed as predicted.
Odometry::Tilt Odometry::prepare_tilt(const cloud::Cloud& cloud, double cloud_time_s) const {
  const auto& poses = trajectory_.poses();
  // Constant-velocity prediction from the last two poses.
  Eigen::Isometry3d predicted = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d motion_per_s = Eigen::Isometry3d::Identity();
  if (poses.size() >= 2) {
    const TimedPose& a = poses[poses.size() - 2];
    const TimedPose& b = poses.back();
    motion_per_s = velocity_between(a, b);
    predicted = scale_motion(a.T_world_lidar, b.T_world_lidar,
                             (cloud_time_s - a.time_s) / (b.time_s - a.time_s));
  } else if (poses.size() == 1) {
    predicted = poses.back().T_world_lidar;
  }
  Tilt tilt;
  tilt.time_s = cloud_time_s;
  tilt.centroids =
      sensor_voxels(cloud, options_.source_voxel_m, options_.min_range_m, options_.max_range_m);
  if (!prior_.empty()) {
    const Eigen::Isometry3d T_start_frame = prior_.pose_at(cloud_time_s).inverse();
    tilt.source = deskew_points(tilt.centroids, [&](double tau_s) {
      return T_start_frame * prior_.pose_at(cloud_time_s + tau_s);
    });
    if (!poses.empty()) {
      const TimedPose& from = options_.map_at_prior ? poses.front() : poses.back();
      predicted =
          from.T_world_lidar * prior_.pose_at(from.time_s).inverse() * prior_.pose_at(cloud_time_s);
    }
  } else {
    if (!rotation_prior_.empty() && !poses.empty()) {
      const TimedPose& last = poses.back();
      predicted.linear() =
          last.T_world_lidar.linear() * gyro_rotation(last.time_s, cloud_time_s);
    }
    tilt.source = deskew(tilt.centroids, cloud_time_s, motion_per_s);
  }
  tilt.predicted = predicted;
  tilt.deskewed_by = motion_per_s;
  return tilt;
}

/// RegistrationOptions::start_up_clouds applies.
bool Odometry::solves_start_up() const {
  return prior_.empty() && options_.backend != IcpBackend::kPointToPoint &&
         options_.start_up_clouds > 0;
}

/// The first start_up_clouds tilts' centroids, kept for smooth_start_up.
void Odometry::keep_for_start_up(const Tilt& tilt) {
  const auto& poses = trajectory_.poses();
  if (solves_start_up() && static_cast<int>(poses.size()) < options_.start_up_clouds) {
    impl_->start_up.push_back(
        {poses.empty() ? 0.0 : tilt.time_s - poses.front().time_s, tilt.centroids, nullptr});
  }
}

/// The tilt's pose: the prediction for the first cloud, else registered (the second cloud
/// by its own fixed point).
Odometry::Step Odometry::register_tilt(Tilt& tilt) {
  Step step;
  step.T_world_lidar = tilt.predicted;
  if (prior_.empty() && trajectory_.size() == 1 && impl_->have_first) {
    register_second_cloud(tilt, step);
  } else if (impl_->map && !impl_->map->empty()) {
    register_against_map(tilt, step);
  }
  return step;
}

void Odometry::register_second_cloud(Tilt& tilt, Step& step) {
  Impl& m = *impl_;
  // Second cloud: no velocity yet, and the first cloud in the map is skewed by the very
  // motion being estimated. Iterate to the fixed point where the velocity that de-skews
  // both clouds is the one their registration measures.
  const TimedPose first = trajectory_.poses().front();
  Eigen::Isometry3d velocity = Eigen::Isometry3d::Identity();
  for (int iteration = 0; iteration < kInitIterations; ++iteration) {
    auto map = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*deskew(m.first_cloud, first.time_s, velocity), *map,
                             first.T_world_lidar.matrix().cast<float>());
    tilt.source = deskew(tilt.centroids, tilt.time_s, velocity);
    const RegistrationResult r = register_clouds(tilt.source, map, step.T_world_lidar, options_);
    const double change = core::translation_error_m(r.T_target_source, step.T_world_lidar);
    step.registration = r;
    step.T_world_lidar = r.T_target_source;
    velocity = velocity_between(first, {tilt.time_s, step.T_world_lidar});
    // With a gyro, its bias is part of the fixed point: the rate that turns its rotation
    // into the registered one de-skews both clouds on the next pass.
    if (!rotation_prior_.empty()) {
      const Eigen::Matrix3d gyro = rotation_prior_.pose_at(first.time_s).linear().transpose() *
                                   rotation_prior_.pose_at(tilt.time_s).linear();
      gyro_correction_ = rotation_rate_between(
          gyro, first.T_world_lidar.linear().transpose() * step.T_world_lidar.linear(),
          tilt.time_s - first.time_s);
    }
    if (iteration > 0 && change < 1e-3) break;
  }
  step.registered = true;
  tilt.source = deskew(tilt.centroids, tilt.time_s, velocity);
  tilt.deskewed_by = velocity;
  auto first_world = std::make_shared<XyzCloud>();
  pcl::transformPointCloud(*deskew(m.first_cloud, first.time_s, velocity), *first_world,
                           first.T_world_lidar.matrix().cast<float>());
  m.recent.front().points_world = first_world;
  if (options_.backend != IcpBackend::kPointToPoint) {
    m.recent.front().covariances_world = m.gicp.covariances_of(first_world);
  }
  m.first_cloud = {};
  m.have_first = false;
}

/// The tilt registered against the local map from the prediction, and once more when the
/// prediction was off.
void Odometry::register_against_map(Tilt& tilt, Step& step) {
  Impl& m = *impl_;
  // kRobust and kGeneralized share GICP's covariances and local map.
  const bool generalized = options_.backend != IcpBackend::kPointToPoint;
  const bool robust = options_.backend == IcpBackend::kRobust;
  // Ours: the first run only sets the de-skew of the second, so it stops at a coarser
  // tail; both runs share the neighbours found (NearestKept measures how far the second
  // de-skew moved each point). Measured while the full tail was 10x tighter than it is
  // now (robust_gicp): stopping it at 10x that tail took 16 % fewer Gauss-Newton steps on
  // sim street seed 1 (mean anchored error on the 14 streets of docs/mapping.md 0.0771 ->
  // 0.0772 m); at 100x (1 mm, 1e-4 rad, as now), 12.0 steps per tilt against 14.8 at 10x
  // (--accurate 18.7 against 24.7), the 14 streets' mean 0.0769 against 0.0772 m
  // (--accurate 0.0291 m both).
  // Why the coarse run is worth stopping early: from the constant-velocity de-skew its
  // steps shrink by only ~0.75x each; de-skewed with the measured velocity, the second
  // run's steps shrink by ~0.25x each (traced on seed 1, --accurate; why the first run
  // converges so slowly was not measured).
  //
  // The first run also keeps the loose Cauchy scale once the settled one has taken over
  // (RegistrationOptions::settled_robust_scale2): under the tight scale it converged more
  // slowly still. --accurate on seed 1: 14.3 against 18.7 steps per tilt; the 14 streets'
  // mean anchored error 0.0291 m both (each street within 0.3 mm).
  std::vector<NearestKept> kept(robust ? tilt.centroids.points.size() : 0);
  bool coarse = robust;
  RegistrationOptions coarse_options = options_;
  coarse_options.robust_scale2 = m.loose_robust_scale2;
  auto run = [&](auto& icp, const Eigen::Isometry3d& guess, RegistrationResult& r) {
    if (robust) {
      r = robust_gicp(*tilt.source, *tilt.source_covariances, *m.map, *m.map_tree,
                      m.map_covariances, guess, coarse ? coarse_options : options_, &kept, coarse);
      return;
    }
    icp.setInputSource(tilt.source);
    if constexpr (std::is_same_v<std::decay_t<decltype(icp)>, CovarianceGicp>) {
      icp.setSourceCovariances(tilt.source_covariances);  // after setInputSource, which resets them
    }
    align(icp, tilt.source, guess, r);
  };
  if (generalized) tilt.source_covariances = m.gicp.covariances_of(tilt.source);
  RegistrationResult& r = step.registration;
  r.target_points = m.map->size();
  generalized ? run(m.gicp, tilt.predicted, r) : run(m.icp, tilt.predicted, r);
  const int first_iterations = r.iterations;
  step.registered = true;
  // The registration measured this cloud's motion since the previous one: de-skew with
  // that velocity and refine (the prediction is off whenever the cart accelerates). The
  // covariances stay: the two de-skews differ by the acceleration over one tilt, which
  // moves neighbouring centroids alike.
  // When the prediction was right to within refine_above_m, so was the velocity and the
  // de-skew error is below that at the tilt's end: no second run.
  const Eigen::Isometry3d correction = tilt.predicted.inverse() * r.T_target_source;
  constexpr double lever_m = 10.0;  // a rotation error seen at 10 m
  if (prior_.empty() &&
      correction.translation().norm() + lever_m * Eigen::AngleAxisd(correction.linear()).angle() >
          options_.refine_above_m) {
    const Eigen::Isometry3d measured =
        velocity_between(trajectory_.poses().back(), {tilt.time_s, r.T_target_source});
    tilt.source = deskew(tilt.centroids, tilt.time_s, measured);
    tilt.deskewed_by = measured;
    coarse = false;
    generalized ? run(m.gicp, r.T_target_source, r) : run(m.icp, r.T_target_source, r);
    r.iterations += first_iterations;
  } else if (robust) {  // the coarse run's tail, to the full tail test
    coarse = false;
    run(m.gicp, r.T_target_source, r);
    r.iterations += first_iterations;
  }
  if (!robust) {  // ours reports it from its last step
    r.fitness_m2 = generalized ? m.gicp.getFitnessScore(options_.max_correspondence_m)
                               : m.icp.getFitnessScore(options_.max_correspondence_m);
  }
  step.T_world_lidar = r.T_target_source;
}

/// The tilt added to the local map, the oldest clouds beyond local_map_clouds dropped.
void Odometry::join_local_map(Tilt& tilt, const Step& step) {
  Impl& m = *impl_;
  const std::size_t clouds = trajectory_.size();  // this one included
  const bool with_prior = !prior_.empty();
  const bool generalized = options_.backend != IcpBackend::kPointToPoint;
  // The cloud joins the local map in the world frame, its covariances rotated with it.
  const Eigen::Isometry3d& T_world_map_cloud =
      options_.map_at_prior ? tilt.predicted : step.T_world_lidar;
  Impl::MapCloud entry;
  entry.points_world = std::make_shared<XyzCloud>();
  pcl::transformPointCloud(*tilt.source, *entry.points_world,
                           T_world_map_cloud.matrix().cast<float>());
  if (generalized && (clouds > 1 || with_prior)) {
    if (!tilt.source_covariances) tilt.source_covariances = m.gicp.covariances_of(tilt.source);
    const Eigen::Matrix3d R = T_world_map_cloud.linear();
    entry.covariances_world = std::make_shared<Covariances>(tilt.source_covariances->size());
    for (std::size_t i = 0; i < tilt.source_covariances->size(); ++i) {
      (*entry.covariances_world)[i] = R * (*tilt.source_covariances)[i] * R.transpose();
    }
  }
  if (!m.anchor.points.empty()) {
    entry.sensor = tilt.centroids;
    entry.time_s = tilt.time_s;
  }
  if (options_.window_clouds > 0 && !with_prior && generalized) {
    const TimedPoints& centroids = tilt.centroids;
    entry.centroids = centroids;
    entry.start_s = tilt.time_s;
    const double duration_s =
        centroids.t_s.empty() ? 0.0 : *std::max_element(centroids.t_s.begin(), centroids.t_s.end());
    entry.end_s = tilt.time_s + duration_s;
    entry.T_world_end =
        step.T_world_lidar * core::from_vector6(core::to_vector6(tilt.deskewed_by) * duration_s);
  }
  entry.serial = ++m.serial;
  m.recent.push_back(entry);
  if (clouds == 1 && !with_prior) {
    m.first_cloud = tilt.centroids;
    m.have_first = true;
    if (options_.reanchor_first_cloud) m.anchor = tilt.centroids;
  }
  while (static_cast<int>(m.recent.size()) > options_.local_map_clouds) m.recent.pop_front();
}

/// RegistrationOptions::window_clouds' window is due on this tilt.
bool Odometry::window_due() const {
  const int clouds = static_cast<int>(trajectory_.size());
  return options_.window_clouds > 0 && prior_.empty() &&
         options_.backend != IcpBackend::kPointToPoint && clouds >= options_.window_start_clouds &&
         static_cast<int>(impl_->recent.size()) > options_.window_clouds &&
         (clouds - options_.window_start_clouds) % options_.window_interval_clouds == 0;
}

/// The next tilt's target, with this tilt in it.
void Odometry::rebuild_target_after_add() {
  // Between windows the merged map is not merged anew: the new cloud joins it as it is.
  if (trajectory_.size() >= 2 || !prior_.empty()) {
    impl_->rebuild_target(options_.backend, options_.merged_local_map_m, window_.solves > 0);
  }
}

/// The start-up's clouds have all come.
bool Odometry::start_up_due() const {
  return solves_start_up() && static_cast<int>(trajectory_.size()) == options_.start_up_clouds;
}

/// The first cloud has just left the local map and awaits its re-anchoring.
bool Odometry::reanchoring_due() const {
  return prior_.empty() && options_.reanchor_first_cloud && !impl_->anchor.points.empty() &&
         static_cast<int>(trajectory_.size()) == std::max(options_.local_map_clouds, 3) + 1;
}

void Odometry::smooth_start_up() {
  Impl& m = *impl_;
  const std::vector<CurveCloud> clouds = std::move(m.start_up);
  m.start_up = {};
  const auto& poses = trajectory_.poses();
  const Eigen::Isometry3d T_world_first = poses.front().T_world_lidar;
  std::vector<std::pair<double, Eigen::Isometry3d>> samples;
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    samples.emplace_back(clouds[k].tau_s, T_world_first.inverse() * poses[k].T_world_lidar);
  }
  const auto start = Clock::now();
  const CurveResult r = solve_curve(clouds, T_world_first, fit_curve(samples, false), false,
                                    nullptr, m.gicp, options_);
  start_up_.time_ms = ms_since(start);
  start_up_.attempted = true;
  start_up_.converged = r.converged;
  start_up_.iterations = r.iterations;
  if (!r.converged) return;
  std::vector<TimedPose> moved = poses;
  double largest_move_m = 0.0;
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    moved[k].T_world_lidar =
        T_world_first * core::from_vector6(curve_vector(r.coefficients, clouds[k].tau_s));
    largest_move_m = std::max(
        largest_move_m, core::translation_error_m(moved[k].T_world_lidar, poses[k].T_world_lidar));
  }
  // A change beyond the correspondence gate is not a refinement: keep the poses.
  if (largest_move_m > options_.max_correspondence_m) return;
  start_up_.applied = true;
  trajectory_ = Trajectory(std::move(moved));
  // The clouds of the local map along the curve (the newest clouds are the start-up's).
  const std::size_t in_map = std::min(clouds.size(), m.recent.size());
  for (std::size_t i = clouds.size() - in_map; i < clouds.size(); ++i) {
    auto& entry = m.recent[m.recent.size() - clouds.size() + i];
    entry.points_world = r.world[i];
    if (!entry.centroids.points.empty()) {  // kept for the windows
      entry.T_world_end = T_world_first * core::from_vector6(curve_vector(
                                              r.coefficients, entry.end_s - poses.front().time_s));
    }
    entry.covariances_world = m.gicp.covariances_of(r.world[i]);
    entry.sensor = {};
  }
  m.anchor = {};  // the curve replaces the re-anchoring
  m.rebuild_target(options_.backend, options_.merged_local_map_m);
}

void Odometry::refine_window() {
  Impl& m = *impl_;
  const auto start = Clock::now();
  const auto w = static_cast<std::size_t>(options_.window_clouds);
  const std::size_t first_entry = m.recent.size() - w;
  const auto& poses = trajectory_.poses();
  const std::size_t first_pose = poses.size() - w;
  const Eigen::Isometry3d base = poses[first_pose].T_world_lidar;
  std::vector<CurveCloud> clouds;
  std::vector<std::pair<double, Eigen::Isometry3d>> samples;
  for (std::size_t i = 0; i < w; ++i) {
    const Impl::MapCloud& entry = m.recent[first_entry + i];
    clouds.push_back(
        {entry.start_s - m.recent[first_entry].start_s, entry.centroids, entry.covariances_world});
    // The guess: through each cloud's poses at its start and end as it is placed now.
    samples.emplace_back(clouds.back().tau_s, base.inverse() * poses[first_pose + i].T_world_lidar);
    samples.emplace_back(entry.end_s - m.recent[first_entry].start_s,
                         base.inverse() * entry.T_world_end);
  }
  // The older clouds of the local map, held fixed (merged as the local map is).
  auto fixed_points = std::make_shared<XyzCloud>();
  auto concatenated = std::make_shared<Covariances>();
  for (std::size_t i = 0; i < first_entry; ++i) {
    *fixed_points += *m.recent[i].points_world;
    concatenated->insert(concatenated->end(), m.recent[i].covariances_world->begin(),
                         m.recent[i].covariances_world->end());
  }
  if (options_.merged_local_map_m > 0.0) {
    fixed_points = downsample(*fixed_points, options_.merged_local_map_m);
    if (static_cast<int>(fixed_points->size()) <
        options_.covariance_neighbours) {  // nothing to hold on to
      m.rebuild_target(options_.backend, options_.merged_local_map_m);
      return;
    }
  }
  auto fixed_tree = std::make_shared<MapTree>();
  fixed_tree->setInputCloud(fixed_points);
  const TargetCovariances fixed_covariances =
      options_.merged_local_map_m > 0.0
          ? TargetCovariances(fixed_points, fixed_tree, options_.covariance_neighbours)
          : TargetCovariances(concatenated);
  const FixedMap fixed{*fixed_points, fixed_covariances, *fixed_tree};
  const CurveResult r =
      solve_curve(clouds, base, fit_curve(samples, true), true, &fixed, m.gicp, options_);
  window_.time_ms += ms_since(start);
  ++window_.solves;
  window_.iterations += r.iterations;
  // The target from here to the next window: the fixed part as merged for the solve, the
  // window's clouds joining it as they are (as new clouds join it between windows). Merging
  // all the clouds anew here measured the same on the 14 sim streets of docs/mapping.md
  // (mean anchored 0.0362 against 0.0363 m) and cost a merge and the covariances of every
  // merged point once per window.
  auto rebuild_from_fixed = [&] {
    if (options_.merged_local_map_m > 0.0 && options_.backend == IcpBackend::kRobust) {
      m.merged_points = fixed_points;
      m.merged_covariances = fixed_covariances;
      m.merged_serial = m.recent[first_entry - 1].serial;
      m.rebuild_target(options_.backend, options_.merged_local_map_m, true);
    } else {
      m.rebuild_target(options_.backend, options_.merged_local_map_m);
    }
  };
  if (!r.converged) {
    ++window_.not_converged;
    rebuild_from_fixed();
    return;
  }
  std::vector<TimedPose> moved = poses;
  for (std::size_t i = 0; i < w; ++i) {
    moved[first_pose + i].T_world_lidar =
        base * core::from_vector6(curve_vector(r.coefficients, clouds[i].tau_s));
    m.recent[first_entry + i].points_world = r.world[i];
    m.recent[first_entry + i].T_world_end =
        base * core::from_vector6(curve_vector(r.coefficients, m.recent[first_entry + i].end_s -
                                                                   m.recent[first_entry].start_s));
    // Covariances: the newest cloud's anew, from where the curve puts its points (its
    // registration de-skewed it with a constant velocity: centimetres off at its far end);
    // the others' turn with their cloud. With a window after every tilt the others' were so
    // computed when they were newest; keeping the registration's for the newest too then
    // gave 11.8 against 10.5 mm mean aligned error on the 14 sim streets of docs/mapping.md.
    // With a window every 3rd tilt and the merged map, no cloud enters a second window: the
    // newest's serve only until the next window merges it into the fixed part, where the
    // merged points get their own; they are the registration's, turned (the 14 streets'
    // errors in RegistrationOptions::accurate()'s comment were measured so).
    const bool used_again = options_.window_interval_clouds < options_.window_clouds ||
                            options_.merged_local_map_m == 0.0;
    if (i + 1 == w && used_again) {
      m.recent[first_entry + i].covariances_world = m.gicp.covariances_of(r.world[i]);
      continue;
    }
    const Eigen::Matrix3d turn = moved[first_pose + i].T_world_lidar.linear() *
                                 poses[first_pose + i].T_world_lidar.linear().transpose();
    auto covariances = std::make_shared<Covariances>(*m.recent[first_entry + i].covariances_world);
    for (auto& S : *covariances) S = turn * S * turn.transpose();
    m.recent[first_entry + i].covariances_world = covariances;
  }
  trajectory_ = Trajectory(std::move(moved));
  rebuild_from_fixed();
}

void Odometry::reanchor_first_cloud() {
  Impl& m = *impl_;
  const TimedPoints anchor = std::move(m.anchor);
  m.anchor = {};
  const auto& poses = trajectory_.poses();
  // The velocity during the first tilt, extrapolated back from the second and third
  // chords (the first chord is the weakly determined one).
  const core::Vector6d twist =
      2.0 * twist_between(poses[1], poses[2]) - twist_between(poses[2], poses[3]);
  const XyzCloud::Ptr source = deskew_points(anchor, core::from_vector6(twist));
  // The clouds of the local map were de-skewed with the velocity known when each came; the
  // first of them with the start-up guess. De-skew them again along the trajectory as it
  // now stands (covariances kept: the change is below a voxel's extent).
  for (auto& c : m.recent) {
    if (c.sensor.points.empty()) continue;
    const Eigen::Isometry3d T_world_start = trajectory_.pose_at(c.time_s);
    const Eigen::Isometry3d T_start_world = T_world_start.inverse();
    const XyzCloud::Ptr in_start = deskew_points(c.sensor, [&](double tau_s) {
      return T_start_world * trajectory_.pose_at(c.time_s + tau_s);
    });
    auto points = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*in_start, *points, T_world_start.matrix().cast<float>());
    c.points_world = points;
    c.sensor = {};
  }
  m.rebuild_target(options_.backend, options_.merged_local_map_m);
  const Eigen::Isometry3d& before = poses.front().T_world_lidar;
  RegistrationResult r;
  if (options_.backend == IcpBackend::kRobust) {
    r = robust_gicp(*source, *m.gicp.covariances_of(source), *m.map, *m.map_tree, m.map_covariances,
                    before, options_);
  } else {
    r = register_clouds(source, m.map, before, options_);
  }
  // The world frame in which the first cloud keeps its pose: W' = C W.
  const Eigen::Isometry3d C = before * r.T_target_source.inverse();
  reanchoring_.attempted = true;
  reanchoring_.registration = r;
  reanchoring_.correction = C;
  // A correction beyond the correspondence gate is not a refinement: keep the start.
  if (!r.converged || (r.T_target_source.translation() - before.translation()).norm() >
                          options_.max_correspondence_m) {
    return;
  }
  reanchoring_.applied = true;
  std::vector<TimedPose> moved;
  moved.reserve(poses.size());
  moved.push_back(poses.front());  // C r = before: the first cloud stays where the map starts
  for (std::size_t k = 1; k < poses.size(); ++k) {
    moved.push_back({poses[k].time_s, C * poses[k].T_world_lidar});
  }
  trajectory_ = Trajectory(std::move(moved));
  const Eigen::Matrix4f C_f = C.matrix().cast<float>();
  const Eigen::Matrix3d R = C.linear();
  for (auto& c : m.recent) {
    auto points = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*c.points_world, *points, C_f);
    c.points_world = points;
    c.T_world_end = C * c.T_world_end;
    if (c.covariances_world) {
      auto covariances = std::make_shared<Covariances>(*c.covariances_world);
      for (auto& S : *covariances) S = R * S * R.transpose();
      c.covariances_world = covariances;
    }
  }
  m.rebuild_target(options_.backend, options_.merged_local_map_m);
}

}  // namespace rgbdt::rgbdt_map
