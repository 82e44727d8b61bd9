#pragma once
/// \file
/// What the parts of rgbdt_map's registration share: not installed. registration.cpp: the
/// aligners' set-up, the tilt's voxel centroids and their de-skew; robust_gicp.cpp: GICP's
/// covariances and robust_gicp; trajectory_curve.cpp: the smooth-curve solve; odometry.cpp
/// uses them all.
#include "rgbdt/rgbdt_map/registration.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "nearest_kept.hpp"
#include "point_tree.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map::detail {

using Clock = std::chrono::steady_clock;
inline double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

using Gicp = pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>;
using Icp = pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>;
using Covariances = Gicp::MatricesVector;

/// A PCL aligner that tells how many iterations it ran.
template <typename Base>
class Counted : public Base {
 public:
  int iterations() const { return this->nr_iterations_; }
};

using MapTree = PointTree;

// ---- robust_gicp.cpp ----------------------------------------------------------------------

/// PCL's GICP, whose per-point covariances Odometry estimates once and reuses.
class CovarianceGicp : public Counted<Gicp> {
 public:
  /// GICP's covariance of each point (Segal et al. 2009): from its k nearest neighbours
  /// (k = covariance_neighbours, the point among them), the plane's normal n is the
  /// eigenvector of their scatter with the smallest eigenvalue, and the covariance is
  /// I - (1 - epsilon) n n^T with epsilon = 0.001: unit spread along the plane, little
  /// across it. PCL's computeCovariances gives the same matrices up to rounding, but
  /// multiplies raw float coordinates into second moments in float (100 m squares to
  /// 1e4 m^2, where floats are 1e-3 m^2 apart, beside a spread of a few 1e-2 m^2 among
  /// 0.25 m voxels) and takes a 3x3 SVD by Jacobi sweeps; here the scatter is centred in
  /// double and the eigenvectors come in closed form (test:
  /// Registration.OursIsAsAccurateThreeKilometresFromTheOrigin). `tree` (optional) is a
  /// search tree of `cloud`.
  std::shared_ptr<Covariances> covariances_of(const XyzCloud::ConstPtr& cloud,
                                              const MapTree* tree = nullptr);

  /// The covariance of point i of `cloud` alone (as covariances_of computes each).
  static Eigen::Matrix3d covariance_at(const XyzCloud& cloud, const MapTree& tree, std::size_t i,
                                       int k);
};

/// The GICP covariances of a target's points, as robust_gicp and solve_curve read them:
/// given whole, or (a merged local map) each computed the first time a correspondence asks
/// for it, then kept. A merged map's covariances need a 20-neighbour search per point,
/// and on sim street seed 1 (`--accurate`) the window's solve and the registrations until
/// the next window matched ~31 % of its points: the rest were never used. A lazy part may be
/// followed by points whose covariances are given (the clouds appended between windows);
/// copies share the lazy part, and what one computes the others read.
class TargetCovariances {
 public:
  TargetCovariances() = default;
  explicit TargetCovariances(std::shared_ptr<const Covariances> given) : given_(std::move(given)) {
    given_data_ = given_->data();
  }
  /// Those of `cloud`, each on first use, from its `tree` (CovarianceGicp::covariance_at).
  TargetCovariances(XyzCloud::ConstPtr cloud, std::shared_ptr<const MapTree> tree, int neighbours);
  /// These, followed by `more` (a copy: the lazy part shared).
  TargetCovariances followed_by(const Covariances& more) const;
  std::size_t size() const { return lazy_size_ + (given_ ? given_->size() : 0); }
  const Eigen::Matrix3d& operator[](std::size_t i) const {
    if (i >= lazy_size_) return given_data_[i - lazy_size_];
    if (!lazy_->ready[i]) {
      lazy_->values[i] =
          CovarianceGicp::covariance_at(*lazy_->cloud, *lazy_->tree, i, lazy_->neighbours);
      lazy_->ready[i] = 1;
    }
    return lazy_->values[i];
  }

 private:
  struct Lazy {
    XyzCloud::ConstPtr cloud;
    std::shared_ptr<const MapTree> tree;
    int neighbours = 0;
    Covariances values;
    std::vector<char> ready;
  };
  std::shared_ptr<Lazy> lazy_;
  std::size_t lazy_size_ = 0;  ///< the first points, lazy_'s
  std::shared_ptr<const Covariances> given_;
  const Eigen::Matrix3d* given_data_ = nullptr;  ///< given_'s, for the points after
};

/// IcpBackend::kRobust: GICP's cost (Segal et al. 2009: the Mahalanobis distance of each
/// correspondence under C_target + R C_source R^T), minimised by Gauss-Newton with a Cauchy
/// weight 1 / (1 + d^2 / robust_scale2) and the correspondences renewed every step.
/// Steps are taken about the source's origin (the sensor), where rotation and translation
/// are least coupled. Converged when a step moves less than translation_epsilon_m and turns
/// less than 1/10 of rotation_epsilon_rad (0.1 mm and 1e-5 rad by default), or when the pose
/// comes back to where it was 2-4 steps before, every step since below the epsilons
/// themselves (the correspondences cycle). Steps shrink by ~0.25x each near the minimum, so
/// a 0.1 mm step leaves ~0.03 mm to go. A test 10x tighter (0.01 mm, 1e-6 rad) takes 13 %
/// (default) and 16 % (--accurate) more Gauss-Newton steps per tilt on the 14 sim streets of
/// docs/mapping.md for the same trajectories (each street's anchored error within 1.4 mm,
/// --accurate within 0.3 mm); 30x looser moves one street by 2.5 mm. target_tree holds
/// `target`. kept (optional): the neighbours of `source`'s points as an earlier run on the
/// same target left them (the points may have moved since: NearestKept measures). coarse:
/// stop at 10x the tail test's thresholds (1 mm and 1e-4 rad), for a run whose pose only
/// sets the de-skew of the next.
RegistrationResult robust_gicp(const XyzCloud& source, const Covariances& source_covariances,
                               const XyzCloud& target, const MapTree& target_tree,
                               const TargetCovariances& target_covariances,
                               const Eigen::Isometry3d& guess, const RegistrationOptions& options,
                               std::vector<NearestKept>* kept = nullptr, bool coarse = false);

// ---- registration.cpp ---------------------------------------------------------------------

void configure(Icp& icp, const RegistrationOptions& options);
void configure(Gicp& gicp, const RegistrationOptions& options);

/// A PCL aligner's float transform as an Isometry, its rotation re-orthonormalised.
Eigen::Isometry3d to_isometry(const Eigen::Matrix4f& M_f);

/// Runs an aligner that already has its target; fills pose, convergence and iterations.
template <typename Aligner>
void align(Aligner& icp, const XyzCloud::ConstPtr& source, const Eigen::Isometry3d& guess,
           RegistrationResult& result) {
  XyzCloud aligned;
  icp.align(aligned, guess.matrix().cast<float>());
  result.converged = icp.hasConverged();
  result.iterations = icp.iterations();
  result.T_target_source = to_isometry(icp.getFinalTransformation());
  result.source_points = source->size();
}

/// Voxel centroids of a tilt in the sensor frame, each with the mean time of its points.
struct TimedPoints {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> t_s;
};

TimedPoints sensor_voxels(const cloud::Cloud& cloud, double voxel_m, double min_range_m,
                          double max_range_m);

/// Centroids moved into the LIDAR frame at the tilt's start with a known motion
/// T_start_(start+tau), evaluated once per millisecond (< 1.5 mm of motion at 1.5 m/s).
template <typename Motion>
XyzCloud::Ptr deskew_points(const TimedPoints& in, const Motion& motion) {
  auto out = std::make_shared<XyzCloud>();
  out->resize(in.points.size());
  long long cached_bin = std::numeric_limits<long long>::min();
  Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
  for (std::size_t i = 0; i < in.points.size(); ++i) {
    const long long bin = std::llround(in.t_s[i] * 1000.0);  // 1 ms, as above
    if (bin != cached_bin) {
      T = motion(bin * 1e-3).template cast<float>();
      cached_bin = bin;
    }
    (*out)[i].getVector3fMap() = T * in.points[i];
  }
  return out;
}

/// Centroids moved into the LIDAR frame at the tilt's start with a constant velocity.
/// De-skewing a centroid at its points' mean time equals the mean of the de-skewed points
/// to first order in the motion (the neglected term is the rotation rate times the
/// covariance of position and time inside one voxel: < 1 mm at 25 cm and 0.2 rad/s).
XyzCloud::Ptr deskew_points(const TimedPoints& in, const Eigen::Isometry3d& motion_per_s);

// ---- trajectory_curve.cpp -----------------------------------------------------------------

/// A stretch of the trajectory as one smooth curve: T_world_lidar(tau) =
/// base * from_vector6(c0 + c1 tau + c2 tau^2 + c3 tau^3), tau from the first cloud's start.
/// A cubic fits the sim street's first 3 s to 0.013 deg and 0.5 mm (a quadratic to 0.1
/// deg). The start-up pins c0 = 0 (its base is the first pose, where the map starts); a
/// window of later clouds leaves it free.
using CurveCoefficients = Eigen::Matrix<double, 24, 1>;

core::Vector6d curve_vector(const CurveCoefficients& c, double tau_s);

struct CurveCloud {
  double tau_s = 0.0;  ///< the cloud's start after the first cloud's
  TimedPoints sensor;
  /// Its GICP covariances in the world, as the guess places it; null: solve_curve computes them.
  std::shared_ptr<const Covariances> covariances_world;
};

/// The coefficients through poses (tau_s, base^-1 T_world_lidar) by least squares on
/// from_vector6's parameters; c0 = 0 unless free_offset.
CurveCoefficients fit_curve(const std::vector<std::pair<double, Eigen::Isometry3d>>& poses,
                            bool free_offset);

/// Older clouds the curve's clouds are registered against as well, held fixed.
struct FixedMap {
  const XyzCloud& points;
  const TargetCovariances& covariances;
  const MapTree& tree;
};

struct CurveResult {
  CurveCoefficients coefficients = CurveCoefficients::Zero();
  bool converged = false;
  int iterations = 0;
  std::vector<XyzCloud::Ptr> world;  ///< each cloud's points along the solved curve
};

/// Every cloud on the curve registered against all the others at once (and against
/// `fixed`, when given), each point placed at the curve's pose at its own time:
/// Gauss-Newton on GICP's cost with the Cauchy loss of robust_gicp, each correspondence
/// between two of the curve's clouds moving at both ends, the correspondences renewed
/// every step. The chord between two start poses gives a tilt the rotation rate of
/// 0.3-0.6 s before it; the curve gives each point the pose at its own time. Covariances:
/// those of each cloud as placed by the guess, in the world (the solve moves it by less
/// than a voxel). Converged when a step moves no pose of the span by more than the
/// epsilons (the correspondences then cycle between sets ~0.04 mm apart).
CurveResult solve_curve(const std::vector<CurveCloud>& clouds, const Eigen::Isometry3d& base,
                        const CurveCoefficients& guess, bool free_offset, const FixedMap* fixed,
                        CovarianceGicp& gicp, const RegistrationOptions& options);

}  // namespace rgbdt::rgbdt_map::detail
