#include "rgbdt/rgbdt_map/registration.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "rgbdt/core/transform.hpp"
#include "nearest_kept.hpp"
#include "point_tree.hpp"

namespace rgbdt::rgbdt_map {
namespace {
using detail::NearestKept;
constexpr int kInitIterations = 6;  ///< fixed-point iterations for the second cloud (converge in 3-4)

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point start) {
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

using MapTree = detail::PointTree;

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
  std::shared_ptr<Covariances> covariances_of(const XyzCloud::ConstPtr& cloud, const MapTree* tree = nullptr) {
    const int k = getCorrespondenceRandomness();
    if (static_cast<int>(cloud->size()) < k) {
      throw std::invalid_argument("GICP covariances: a cloud of " + std::to_string(cloud->size()) +
                                  " points after downsampling, expected at least covariance_neighbours = " +
                                  std::to_string(k));
    }
    MapTree own;
    if (!tree) {
      own.setInputCloud(cloud);
      tree = &own;
    }
    auto out = std::make_shared<Covariances>(cloud->size());
    for (std::size_t i = 0; i < cloud->size(); ++i) (*out)[i] = covariance_at(*cloud, *tree, i, k);
    return out;
  }

  /// The covariance of point i of `cloud` alone (as covariances_of computes each).
  static Eigen::Matrix3d covariance_at(const XyzCloud& cloud, const MapTree& tree, std::size_t i, int k) {
    constexpr double kEpsilon = 0.001;  // PCL's gicp_epsilon_
    thread_local std::vector<int> index;
    thread_local std::vector<float> distance2;
    index.resize(static_cast<std::size_t>(k));
    distance2.resize(static_cast<std::size_t>(k));
    const int found = tree.nearestKSearch(cloud[i], k, index, distance2);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j = 0; j < found; ++j) mean += cloud[static_cast<std::size_t>(index[j])].getVector3fMap().cast<double>();
    mean /= found;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int j = 0; j < found; ++j) {
      const Eigen::Vector3d d = cloud[static_cast<std::size_t>(index[j])].getVector3fMap().cast<double>() - mean;
      scatter.noalias() += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(scatter / found);
    const Eigen::Vector3d normal = solver.eigenvectors().col(0);  // eigenvalues ascending
    return Eigen::Matrix3d::Identity() - (1.0 - kEpsilon) * normal * normal.transpose();
  }
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
  TargetCovariances(XyzCloud::ConstPtr cloud, std::shared_ptr<const MapTree> tree, int neighbours)
      : lazy_(std::make_shared<Lazy>()) {
    if (static_cast<int>(cloud->size()) < neighbours) {  // as CovarianceGicp::covariances_of
      throw std::invalid_argument("GICP covariances: a cloud of " + std::to_string(cloud->size()) +
                                  " points after downsampling, expected at least covariance_neighbours = " +
                                  std::to_string(neighbours));
    }
    lazy_->values.resize(cloud->size());
    lazy_->ready.assign(cloud->size(), 0);
    lazy_->cloud = std::move(cloud);
    lazy_->tree = std::move(tree);
    lazy_->neighbours = neighbours;
    lazy_size_ = lazy_->values.size();
  }
  /// These, followed by `more` (a copy: the lazy part shared).
  TargetCovariances followed_by(const Covariances& more) const {
    TargetCovariances out;
    out.lazy_ = lazy_;
    out.lazy_size_ = lazy_size_;
    auto tail = std::make_shared<Covariances>();
    tail->reserve((given_ ? given_->size() : 0) + more.size());
    if (given_) tail->insert(tail->end(), given_->begin(), given_->end());
    tail->insert(tail->end(), more.begin(), more.end());
    out.given_ = std::move(tail);
    out.given_data_ = out.given_->data();
    return out;
  }
  std::size_t size() const { return lazy_size_ + (given_ ? given_->size() : 0); }
  const Eigen::Matrix3d& operator[](std::size_t i) const {
    if (i >= lazy_size_) return given_data_[i - lazy_size_];
    if (!lazy_->ready[i]) {
      lazy_->values[i] = CovarianceGicp::covariance_at(*lazy_->cloud, *lazy_->tree, i, lazy_->neighbours);
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
  T.linear() = Eigen::Quaterniond(Eigen::Matrix3d(M.block<3, 3>(0, 0))).normalized().toRotationMatrix();
  T.translation() = M.block<3, 1>(0, 3);
  return T;
}

/// Runs an aligner that already has its target; fills pose, convergence and iterations.
template <typename Aligner>
void align(Aligner& icp, const XyzCloud::ConstPtr& source, const Eigen::Isometry3d& guess, RegistrationResult& result) {
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

TimedPoints sensor_voxels(const cloud::Cloud& cloud, double voxel_m, double min_range_m, double max_range_m) {
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
XyzCloud::Ptr deskew_points(const TimedPoints& in, const Eigen::Isometry3d& motion_per_s) {
  const core::Vector6d twist = core::to_vector6(motion_per_s);
  return deskew_points(in, [&twist](double tau_s) { return core::from_vector6(twist * tau_s); });
}

/// The constant twist that moves pose a to pose b in their time apart (per second, in a's frame).
core::Vector6d twist_between(const TimedPose& a, const TimedPose& b) {
  return core::to_vector6(a.T_world_lidar.inverse() * b.T_world_lidar) / (b.time_s - a.time_s);
}

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
/// --accurate within 0.3 mm); 30x looser moves one street by 2.5 mm. target_tree holds `target`. kept (optional): the neighbours of `source`'s points
/// as an earlier run on the same target left them (the points may have moved since:
/// NearestKept measures). coarse: stop at 10x the tail test's thresholds (1 mm and 1e-4
/// rad), for a run whose pose only sets the de-skew of the next.
RegistrationResult robust_gicp(const XyzCloud& source, const Covariances& source_covariances,
                               const XyzCloud& target, const MapTree& target_tree,
                               const TargetCovariances& target_covariances, const Eigen::Isometry3d& guess,
                               const RegistrationOptions& options, std::vector<NearestKept>* kept = nullptr,
                               bool coarse = false) {
  RegistrationResult result;
  result.source_points = source.size();
  result.target_points = target.size();
  Eigen::Isometry3d T = guess;
  const double gate2 = options.max_correspondence_m * options.max_correspondence_m;
  std::vector<NearestKept> own;
  if (!kept) {
    own.resize(source.size());
    kept = &own;
  } else if (kept->size() != source.size()) {
    throw std::logic_error("robust_gicp: kept neighbours of " + std::to_string(kept->size()) + " points for a source of " +
                           std::to_string(source.size()));
  }
  // The poses of the last iterations, to tell a cycle (see below).
  struct Visited {
    Eigen::Isometry3d T;
    bool fine_step_after;  ///< the step that left this pose was below the epsilons
  };
  constexpr std::size_t kCycleLength = 4;
  std::vector<Visited> recent{{guess, false}};
  // The tail test: a move this small is no move at all.
  const double tail = coarse ? 10.0 : 1.0;
  auto settled = [&options, tail](double translation_m, double angle_rad) {
    return translation_m < tail * options.translation_epsilon_m && angle_rad < tail * 0.1 * options.rotation_epsilon_rad;
  };
  // Each correspondence's information matrix M = (C_target + R C_source R^T)^-1, kept while
  // the point's nearest target point stays the same (most of the steps after the first few)
  // and the cloud has turned by less than kKeepInformationRad since the kept ones were made:
  // a source plane's normal tilted by d adds ~d^2 = 1e-6 m^2 to the pair's variance along the
  // target's normal, 0.05 % of its 2 x 0.001. Beyond that all are made anew with the current R, so a guess
  // degrees off (a standalone register_clouds) still ends on the covariances of its answer.
  // callgrind (seed 1, 40 tilts): 3.4 % fewer instructions in the default, 2.0 % in
  // --accurate. The 14 sim streets: the default's anchored error each within 2.9 mm (mean
  // 0.0768 -> 0.0769 m), --accurate's within 0.3 mm but seed 7's, 2.9 mm (mean 0.0291 ->
  // 0.0293 m). Kept with the guess's rotation throughout (as solve_curve places its
  // covariances) instead, the default's streets moved by up to 8.5 cm each way.
  constexpr double kKeepInformationRad = 1e-3;
  struct KeptInformation {
    std::size_t j = NearestKept::kNone;  ///< the target point M was made with
    Eigen::Matrix3d M;
  };
  std::vector<KeptInformation> information(source.size());
  Eigen::Matrix3d R_kept = guess.linear();  ///< the rotation the kept M were made with
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const Eigen::Vector3d c = T.translation();
    const Eigen::Matrix3d R = T.linear();
    if (Eigen::AngleAxisd(R_kept.transpose() * R).angle() > kKeepInformationRad) {
      for (KeptInformation& k : information) k.j = NearestKept::kNone;
      R_kept = R;
    }
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sum_distance2 = 0.0;
    std::size_t inliers = 0;
    for (std::size_t i = 0; i < source.size(); ++i) {
      const Eigen::Vector3d q = T * source[i].getVector3fMap().cast<double>();
      pcl::PointXYZ query;
      query.getVector3fMap() = q.cast<float>();
      const std::size_t j = (*kept)[i].nearest(
          query, 0.0f,
          [&target_tree](const pcl::PointXYZ& at, std::vector<int>& found, std::vector<float>& found_distance2, int k) {
            return target_tree.nearestKSearch(at, k, found, found_distance2);
          },
          [&target](std::size_t k) { return target[k].getVector3fMap(); });
      if (j == NearestKept::kNone) continue;
      const Eigen::Vector3d r = q - target[j].getVector3fMap().cast<double>();
      if (r.squaredNorm() > gate2) continue;
      KeptInformation& kept_M = information[i];
      if (kept_M.j != j) {
        kept_M.j = j;
        kept_M.M = (target_covariances[j] + R_kept * source_covariances[i] * R_kept.transpose()).inverse();
      }
      const Eigen::Matrix3d& M = kept_M.M;
      const double w = 1.0 / (1.0 + r.dot(M * r) / options.robust_scale2);
      // d(exp(w) (q - c) + c + t) / d(w, t) at 0 is J = [A I] with A = -[q - c]x, so
      // J^T M J = [A^T M A, A^T M; M A, M] and J^T M r = [A^T M r; M r]: a third of the
      // multiplications of the dense 3x6 product.
      const Eigen::Vector3d v = q - c;
      Eigen::Matrix3d A;
      A << 0.0, v.z(), -v.y(),
          -v.z(), 0.0, v.x(),
          v.y(), -v.x(), 0.0;
      const Eigen::Matrix3d wMA = w * (M * A);
      const Eigen::Vector3d wMr = w * (M * r);
      H.topLeftCorner<3, 3>().noalias() += A.transpose() * wMA;
      H.topRightCorner<3, 3>() += wMA.transpose();
      H.bottomLeftCorner<3, 3>() += wMA;
      H.bottomRightCorner<3, 3>() += w * M;
      g.head<3>().noalias() += A.transpose() * wMr;
      g.tail<3>() += wMr;
      sum_distance2 += r.squaredNorm();
      ++inliers;
    }
    if (inliers < 6) break;  // nothing to align: keep the last pose, not converged
    const Eigen::Matrix<double, 6, 1> delta = -H.ldlt().solve(g);
    const Eigen::Matrix3d turn = core::from_vector6((core::Vector6d() << delta.head<3>(), 0, 0, 0).finished()).linear();
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = turn;
    step.translation() = c - turn * c + delta.tail<3>();
    T = step * T;
    result.iterations = iteration + 1;
    result.fitness_m2 = sum_distance2 / static_cast<double>(inliers);
    const double step_m = delta.tail<3>().norm(), step_rad = delta.head<3>().norm();
    if (settled(step_m, step_rad)) {
      result.converged = true;
      break;
    }
    // Renewed correspondences can cycle through two to four sets whose minima lie hundredths
    // of a millimetre apart: the steps then go round for good. Back where it was two to four
    // steps ago, with every step of the cycle below the epsilons, is converged too.
    const bool fine_step = step_m < options.translation_epsilon_m && step_rad < options.rotation_epsilon_rad;
    recent.back().fine_step_after = fine_step;
    for (std::size_t back = 2; fine_step && back <= recent.size(); ++back) {
      const Visited& then = recent[recent.size() - back];
      if (!then.fine_step_after) break;  // every step since then must be fine
      const Eigen::Isometry3d cycle = then.T.inverse() * T;
      if (settled(cycle.translation().norm(), Eigen::AngleAxisd(cycle.linear()).angle())) {
        result.converged = true;
        break;
      }
    }
    if (result.converged) break;
    if (recent.size() == kCycleLength) recent.erase(recent.begin());
    recent.push_back({T, false});
  }
  result.T_target_source = T;
  return result;
}

/// A stretch of the trajectory as one smooth curve: T_world_lidar(tau) =
/// base * from_vector6(c0 + c1 tau + c2 tau^2 + c3 tau^3), tau from the first cloud's start.
/// A cubic fits the sim street's first 3 s to 0.013 deg and 0.5 mm (a quadratic to 0.1
/// deg). The start-up pins c0 = 0 (its base is the first pose, where the map starts); a
/// window of later clouds leaves it free.
using CurveCoefficients = Eigen::Matrix<double, 24, 1>;

core::Vector6d curve_vector(const CurveCoefficients& c, double tau_s) {
  return c.segment<6>(0) + tau_s * (c.segment<6>(6) + tau_s * (c.segment<6>(12) + tau_s * c.segment<6>(18)));
}

struct CurveCloud {
  double tau_s = 0.0;  ///< the cloud's start after the first cloud's
  TimedPoints sensor;
  /// Its GICP covariances in the world, as the guess places it; null: solve_curve computes them.
  std::shared_ptr<const Covariances> covariances_world;
};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

/// The left Jacobian of SO(3) at the rotation vector w: R(w + d) = exp(J_l(w) d) R(w), so
/// d(R(w) x)/dw = -[R(w) x]x J_l(w).
Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  const Eigen::Matrix3d W = skew(w);
  if (theta < 1e-9) return Eigen::Matrix3d::Identity() + 0.5 * W;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W + (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

/// A point's derivative by the from_vector6 parameters of the curve at its time tau; by
/// the 24 coefficients it is [J, tau J, tau^2 J, tau^3 J].
struct PointDerivative {
  Eigen::Matrix<double, 3, 6> J;
  double tau = 0.0;
};

/// The Gauss-Newton normal equations of a curve, accumulated in 6x6 blocks: a term's
/// Jacobian is a Kronecker product of the powers of its time with a 3x6 J, so the blocks
/// of one end's J^T M J differ only by tau^(k+l) and seven sums hold all sixteen; only the
/// product of the two ends of a correspondence needs its sixteen blocks. A term against the
/// fixed map costs a quarter of the multiplications of the 24-wide product, a term between
/// two moving clouds about as many, and neither goes through Eigen's general product
/// kernel (12 % of a profiled --accurate run before).
class CurveNormalEquations {
 public:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  /// gradient_only: accumulate g alone (the caller keeps an earlier H).
  explicit CurveNormalEquations(bool gradient_only = false) : gradient_only_(gradient_only) {
    for (auto& m : moment_) m.setZero();
    for (auto& m : cross_) m.setZero();
    for (auto& v : gradient_) v.setZero();
  }

  /// The residual r = a's point - b's point (b null: a fixed point) with information M,
  /// under the Cauchy weight 1 / (1 + r^T M r / scale2).
  void add(const PointDerivative& a, const PointDerivative* b, const Eigen::Matrix3d& M, const Eigen::Vector3d& r,
           double scale2) {
    const Eigen::Vector3d Mr = M * r;
    const double weight = 1.0 / (1.0 + r.dot(Mr) / scale2);
    if (gradient_only_) {
      const Eigen::Vector3d wMr = weight * Mr;
      add_gradient(a.tau, a.J.transpose() * wMr);
      if (b) add_gradient(b->tau, -(b->J.transpose() * wMr));
      return;
    }
    const Eigen::Matrix<double, 6, 3> Ga = weight * a.J.transpose() * M;
    add_end(a.tau, Ga * a.J, Ga * r);
    if (!b) return;
    const Eigen::Matrix<double, 6, 3> Gb = weight * b->J.transpose() * M;
    add_end(b->tau, Gb * b->J, -(Gb * r));
    const Matrix6d A = Ga * b->J;
    const std::array<double, 4> pa = powers(a.tau), pb = powers(b->tau);
    for (int k = 0; k < 4; ++k) {
      for (int l = 0; l < 4; ++l) cross_[4 * k + l].noalias() -= (pa[k] * pb[l]) * A;
    }
  }

  void assemble_gradient(Eigen::Matrix<double, 24, 1>& g) const {
    for (int k = 0; k < 4; ++k) g.segment<6>(6 * k) = gradient_[k];
  }

  void assemble(Eigen::Matrix<double, 24, 24>& H, Eigen::Matrix<double, 24, 1>& g) const {
    for (int k = 0; k < 4; ++k) {
      g.segment<6>(6 * k) = gradient_[k];
      for (int l = 0; l < 4; ++l) {
        H.block<6, 6>(6 * k, 6 * l) = moment_[k + l] + cross_[4 * k + l] + cross_[4 * l + k].transpose();
      }
    }
  }

 private:
  static std::array<double, 4> powers(double tau) { return {1.0, tau, tau * tau, tau * tau * tau}; }

  void add_gradient(double tau, const core::Vector6d& v) {
    double t = 1.0;
    for (int s = 0; s < 4; ++s, t *= tau) gradient_[s].noalias() += t * v;
  }

  void add_end(double tau, const Matrix6d& A, const core::Vector6d& v) {
    double t = 1.0;
    for (int s = 0; s < 7; ++s, t *= tau) {
      moment_[s].noalias() += t * A;
      if (s < 4) gradient_[s].noalias() += t * v;
    }
  }

  std::array<Matrix6d, 7> moment_;  ///< sum of tau^s J^T M J per end, s = k + l
  std::array<Matrix6d, 16> cross_;  ///< block (k, l) of the products of the two ends
  std::array<core::Vector6d, 4> gradient_;
  bool gradient_only_ = false;
};

/// The coefficients through poses (tau_s, base^-1 T_world_lidar) by least squares on
/// from_vector6's parameters; c0 = 0 unless free_offset.
CurveCoefficients fit_curve(const std::vector<std::pair<double, Eigen::Isometry3d>>& poses, bool free_offset) {
  const int first = free_offset ? 0 : 1;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(poses.size()) * 6, (4 - first) * 6);
  Eigen::VectorXd b(static_cast<Eigen::Index>(poses.size()) * 6);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const auto row = static_cast<Eigen::Index>(k) * 6;
    for (int power = first; power < 4; ++power) {
      A.block<6, 6>(row, (power - first) * 6) = std::pow(poses[k].first, power) * Eigen::Matrix<double, 6, 6>::Identity();
    }
    b.segment<6>(row) = core::to_vector6(poses[k].second);
  }
  CurveCoefficients c = CurveCoefficients::Zero();
  c.tail((4 - first) * 6) = A.colPivHouseholderQr().solve(b);
  return c;
}

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
                        CovarianceGicp& gicp, const RegistrationOptions& options) {
  CurveResult result;
  result.coefficients = guess;
  const std::size_t n = clouds.size();
  const double gate2 = options.max_correspondence_m * options.max_correspondence_m;
  double tau_max = 0.0;
  for (const auto& c : clouds) {
    for (float t : c.sensor.t_s) tau_max = std::max(tau_max, c.tau_s + t);
  }
  auto place = [&](const CurveCoefficients& c) {
    std::vector<XyzCloud::Ptr> world(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double tau0 = clouds[i].tau_s;
      world[i] = deskew_points(clouds[i].sensor, [&c, &base, tau0](double t) {
        return Eigen::Isometry3d(base * core::from_vector6(curve_vector(c, tau0 + t)));
      });
    }
    return world;
  };
  std::vector<std::shared_ptr<const Covariances>> covariances(n);
  std::vector<XyzCloud::Ptr> guessed;
  for (std::size_t i = 0; i < n; ++i) {
    covariances[i] = clouds[i].covariances_world;
    if (covariances[i]) continue;
    if (guessed.empty()) guessed = place(guess);
    covariances[i] = gicp.covariances_of(guessed[i]);
  }
  const Eigen::Matrix3d R_base = base.linear();
  std::vector<std::vector<NearestKept>> kept_others(n), kept_fixed(n);
  for (std::size_t i = 0; i < n; ++i) {
    kept_others[i].resize(clouds[i].sensor.points.size());
    kept_fixed[i].resize(clouds[i].sensor.points.size());
  }
  std::vector<float> moved(n, 0.0f);  // per cloud, the sum over steps of its points' largest move
  // Per cloud, a search tree of the other clouds, kept across the steps (built when a point
  // first needs a search, and anew only when NearestKept cannot tell the nearest from it:
  // the clouds move by millimetres per step after the first), and their move bound then.
  std::vector<std::unique_ptr<MapTree>> others_tree(n);
  std::vector<float> others_tree_moved(n, 0.0f);
  std::vector<XyzCloud::Ptr> previous;
  // Once a step moves no pose by more than 30x the epsilons (3 mm and 3e-3 rad), the steps
  // after it keep its H (factorised) and accumulate g alone: the minimum is where g = 0
  // whatever H, and there the correspondences barely change from step to step, nor H with
  // them. A term of g costs ~1/15 of the multiplications of its H. On sim street seed 1
  // (--accurate) 103 of the 191 steps of the windows and the start-up kept H, the steps
  // per window stayed 4.5, and the 14 streets of docs/mapping.md each moved by <= 0.2 mm
  // (mean anchored error 0.0291 m both). Kept from 100x on (after the first step), the
  // steps per window went from 4.5 to 6.5.
  constexpr double kKeepHessianBelow = 30.0;
  Eigen::LDLT<Eigen::Matrix<double, 24, 24>> factor;
  bool factored = false, small_step = false;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const CurveCoefficients c = result.coefficients;
    const auto world = place(c);
    // Each point's derivative by the from_vector6 parameters at its time (the 24
    // coefficients scale it by 1, tau, tau^2, tau^3): [-[y]x R_base J_l(w), R_base] with
    // y = R_base R(w) x. R(w) and R_base J_l(w) are shared by a 1 ms bin, as in `place`.
    std::vector<std::vector<PointDerivative>> derivative(n);
    for (std::size_t i = 0; i < n; ++i) {
      const TimedPoints& sensor = clouds[i].sensor;
      derivative[i].resize(sensor.points.size());
      long long cached_bin = std::numeric_limits<long long>::min();
      Eigen::Matrix3d R = Eigen::Matrix3d::Identity(), B = R_base;
      for (std::size_t p = 0; p < sensor.points.size(); ++p) {
        const long long bin = std::llround(sensor.t_s[p] * 1000.0);
        if (bin != cached_bin) {
          const Eigen::Vector3d w = curve_vector(c, clouds[i].tau_s + bin * 1e-3).head<3>();
          R = core::rotation_from_vector(w);
          B = R_base * left_jacobian(w);
          cached_bin = bin;
        }
        PointDerivative& d = derivative[i][p];
        d.J.leftCols<3>() = -skew(R_base * (R * sensor.points[p].cast<double>())) * B;
        d.J.rightCols<3>() = R_base;
        d.tau = clouds[i].tau_s + sensor.t_s[p];
      }
    }
    // How far the points moved in this step: bounds for the kept neighbours (NearestKept).
    for (std::size_t i = 0; i < n; ++i) {
      float largest = 0.0f;
      if (iteration > 0) {
        for (std::size_t p = 0; p < world[i]->size(); ++p) {
          largest = std::max(largest, ((*world[i])[p].getVector3fMap() - (*previous[i])[p].getVector3fMap()).norm());
        }
      }
      moved[i] += largest;
    }
    previous = world;
    const bool keep_hessian = factored && small_step;
    CurveNormalEquations normal(keep_hessian);
    std::size_t inliers = 0;
    for (std::size_t i = 0; i < n; ++i) {
      // The other clouds on the curve, in order (their tree: others_tree[i]).
      std::vector<std::size_t> offset(n, 0);
      std::size_t others_size = 0;
      float others_moved = 0.0f;  // a bound on how far any of their points moved since the first step
      for (std::size_t j = 0; j < n; ++j) {
        if (j == i) continue;
        offset[j] = others_size;
        others_size += world[j]->size();
        others_moved += moved[j];
      }
      auto search_others = [&](const pcl::PointXYZ& query, std::vector<int>& index, std::vector<float>& distance2, int k) {
        if (!others_tree[i]) {
          auto others = std::make_shared<XyzCloud>();
          for (std::size_t j = 0; j < n; ++j) {
            if (j != i) *others += *world[j];
          }
          others_tree[i] = std::make_unique<MapTree>();
          others_tree[i]->setInputCloud(others);
          others_tree_moved[i] = others_moved;
        }
        return others_tree[i]->nearestKSearch(query, k, index, distance2);
      };
      auto owner = [&](std::size_t k) {  // (cloud, point) of a point of `others`
        std::size_t j = 0;
        while (j == i || k >= offset[j] + world[j]->size()) ++j;
        return std::make_pair(j, k - offset[j]);
      };
      for (std::size_t p = 0; p < world[i]->size(); ++p) {
        const pcl::PointXYZ& query = (*world[i])[p];
        const PointDerivative& a = derivative[i][p];
        auto others_position = [&](std::size_t k) {
          const auto [j, q] = owner(k);
          return (*world[j])[q].getVector3fMap();
        };
        std::size_t k = kept_others[i][p].nearest_in_stale(query, others_moved, search_others, others_position,
                                                           others_tree_moved[i]);
        if (k == NearestKept::kStale) {  // the tree is too old to tell: build it anew
          others_tree[i].reset();
          k = kept_others[i][p].nearest_in_stale(query, others_moved, search_others, others_position,
                                                 others_tree_moved[i]);
        }
        if (k != NearestKept::kNone) {
          const auto [j, q] = owner(k);
          const Eigen::Vector3d r = (query.getVector3fMap() - (*world[j])[q].getVector3fMap()).cast<double>();
          if (r.squaredNorm() <= gate2) {
            const Eigen::Matrix3d M = ((*covariances[i])[p] + (*covariances[j])[q]).inverse();
            normal.add(a, &derivative[j][q], M, r, options.robust_scale2);
            ++inliers;
          }
        }
        if (!fixed) continue;
        auto search_fixed = [&fixed](const pcl::PointXYZ& at, std::vector<int>& index, std::vector<float>& distance2,
                                     int k) { return fixed->tree.nearestKSearch(at, k, index, distance2); };
        auto fixed_position = [&fixed](std::size_t k) { return fixed->points[k].getVector3fMap(); };
        const std::size_t f = kept_fixed[i][p].nearest(query, 0.0f, search_fixed, fixed_position);
        if (f != NearestKept::kNone) {
          const Eigen::Vector3d r = (query.getVector3fMap() - fixed->points[f].getVector3fMap()).cast<double>();
          if (r.squaredNorm() <= gate2) {
            const Eigen::Matrix3d M = ((*covariances[i])[p] + fixed->covariances[f]).inverse();
            normal.add(a, nullptr, M, r, options.robust_scale2);
            ++inliers;
          }
        }
      }
    }
    if (inliers < 24) break;
    Eigen::Matrix<double, 24, 1> g;
    if (keep_hessian) {
      normal.assemble_gradient(g);
    } else {
      Eigen::Matrix<double, 24, 24> H;
      normal.assemble(H, g);
      if (!free_offset) {  // c0 stays 0: solve for the other coefficients only
        H.topRows<6>().setZero();
        H.leftCols<6>().setZero();
        H.topLeftCorner<6, 6>().setIdentity();
      }
      factor.compute(H);
      factored = true;
    }
    if (!free_offset) g.head<6>().setZero();
    const CurveCoefficients delta = -factor.solve(g);
    result.coefficients += delta;
    result.iterations = iteration + 1;
    // The step's largest effect on a pose over the span.
    double step_m = 0.0, step_rad = 0.0;
    for (int k = 0; k <= 10; ++k) {
      const core::Vector6d d = curve_vector(delta, tau_max * k / 10.0);
      step_rad = std::max(step_rad, d.head<3>().norm());
      step_m = std::max(step_m, d.tail<3>().norm());
    }
    if (step_m < options.translation_epsilon_m && step_rad < options.rotation_epsilon_rad) {
      result.converged = true;
      break;
    }
    small_step = step_m < kKeepHessianBelow * options.translation_epsilon_m &&
                 step_rad < kKeepHessianBelow * options.rotation_epsilon_rad;
  }
  result.world = place(result.coefficients);
  return result;
}

}  // namespace

const char* to_string(IcpBackend backend) {
  switch (backend) {
    case IcpBackend::kRobust: return "rgicp";
    case IcpBackend::kGeneralized: return "gicp";
    case IcpBackend::kPointToPoint: return "icp";
  }
  return "?";
}

IcpBackend icp_backend_from_string(const std::string& name) {
  if (name == "rgicp") return IcpBackend::kRobust;
  if (name == "gicp") return IcpBackend::kGeneralized;
  if (name == "icp") return IcpBackend::kPointToPoint;
  throw std::invalid_argument("ICP backend '" + name + "' unknown, expected 'rgicp', 'gicp' or 'icp'");
}

std::string RegistrationOptions::validate() const {
  std::ostringstream os;
  if (!(source_voxel_m > 0.0)) os << "source_voxel_m = " << source_voxel_m << ", expected > 0; ";
  if (!(max_correspondence_m > 0.0)) os << "max_correspondence_m = " << max_correspondence_m << ", expected > 0; ";
  if (max_iterations < 1) os << "max_iterations = " << max_iterations << ", expected >= 1; ";
  if (!(translation_epsilon_m > 0.0)) os << "translation_epsilon_m = " << translation_epsilon_m << ", expected > 0; ";
  if (!(rotation_epsilon_rad > 0.0)) os << "rotation_epsilon_rad = " << rotation_epsilon_rad << ", expected > 0; ";
  if (!(robust_scale2 > 0.0)) os << "robust_scale2 = " << robust_scale2 << ", expected > 0; ";
  if (!(settled_robust_scale2 >= 0.0)) {
    os << "settled_robust_scale2 = " << settled_robust_scale2 << ", expected 0 (off) or > 0; ";
  }
  if (settled_from_cloud < 2) os << "settled_from_cloud = " << settled_from_cloud << ", expected >= 2; ";
  if (window_clouds != 0 && (window_clouds < 2 || window_clouds >= local_map_clouds)) {
    os << "window_clouds = " << window_clouds << ", expected 0 (off) or 2 to local_map_clouds - 1 = "
       << local_map_clouds - 1 << "; ";
  }
  if (window_interval_clouds < 1) os << "window_interval_clouds = " << window_interval_clouds << ", expected >= 1; ";
  if (window_clouds != 0 && window_start_clouds <= window_clouds) {
    os << "window_start_clouds = " << window_start_clouds << ", expected > window_clouds = " << window_clouds << "; ";
  }
  if (start_up_clouds != 0 && (start_up_clouds < 4 || start_up_clouds > 8)) {
    os << "start_up_clouds = " << start_up_clouds << ", expected 0 (off) or 4-8; ";
  }
  if (!(merged_local_map_m >= 0.0 && merged_local_map_m < 10.0)) {
    os << "merged_local_map_m = " << merged_local_map_m << ", expected 0 (off) or a voxel size in m; ";
  }
  if (covariance_neighbours < 3) os << "covariance_neighbours = " << covariance_neighbours << ", expected >= 3; ";
  if (optimizer_iterations < 1) os << "optimizer_iterations = " << optimizer_iterations << ", expected >= 1; ";
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

RegistrationResult register_clouds(const XyzCloud::ConstPtr& source, const XyzCloud::ConstPtr& target,
                                   const Eigen::Isometry3d& guess, const RegistrationOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("RegistrationOptions: " + why);
  }
  const std::size_t min_points = std::max<std::size_t>(10, options.covariance_neighbours);
  if (!source || !target || source->size() < min_points || target->size() < min_points) {
    throw std::invalid_argument("register_clouds: need at least " + std::to_string(min_points) +
                                " source and target points, got " + std::to_string(source ? source->size() : 0) +
                                " and " + std::to_string(target ? target->size() : 0));
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
    const RegistrationResult r = robust_gicp(*source, *estimator.covariances_of(source), *target, tree,
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

/// The local map: the last clouds in the world frame with their GICP covariances, and
/// the aligners holding it as their target (its search tree is built once per tilt and
/// serves both registrations of the tilt).
struct Odometry::Impl {
  struct MapCloud {
    XyzCloud::Ptr points_world;
    std::shared_ptr<Covariances> covariances_world;  ///< null for point-to-point ICP
    TimedPoints sensor;  ///< the centroids in the sensor frame, while the first cloud awaits its re-anchoring
    TimedPoints centroids;  ///< the centroids in the sensor frame, for RegistrationOptions::window_clouds
    double start_s = 0.0;   ///< the cloud's time, with `centroids`
    double end_s = 0.0;     ///< its last centroid's time, with `centroids`
    Eigen::Isometry3d T_world_end = Eigen::Isometry3d::Identity();  ///< the pose it is placed with at end_s
    double time_s = 0.0;
    long serial = 0;
  };
  std::deque<MapCloud> recent;
  XyzCloud::Ptr map;
  CovarianceGicp gicp;
  Counted<Icp> icp;
  std::shared_ptr<MapTree> map_tree = std::make_shared<MapTree>();  ///< kRobust: search tree of `map`
  TargetCovariances map_covariances;  ///< kRobust: those of `map`
  TimedPoints first_cloud;  ///< the first tilt's centroids, until a velocity is known to de-skew them
  bool have_first = false;
  TimedPoints anchor;  ///< the first tilt's centroids, until reanchor_first_cloud
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
      map_tree = std::make_shared<MapTree>();  // a new one: the merged part's lazy covariances keep theirs
      map_tree->setInputCloud(map);
      map_covariances = merged_covariances.followed_by(appended);
      return;
    }
    const bool generalized = backend != IcpBackend::kPointToPoint;
    map = std::make_shared<XyzCloud>();
    auto covariances = std::make_shared<Covariances>();
    for (const auto& c : recent) {
      *map += *c.points_world;
      if (generalized) covariances->insert(covariances->end(), c.covariances_world->begin(), c.covariances_world->end());
    }
    const bool merge = merge_m > 0.0 && generalized && recent.size() >= 2;
    if (merge) map = downsample(*map, merge_m);
    if (backend == IcpBackend::kRobust) {
      map_tree = std::make_shared<MapTree>();  // a new one: lazy covariances keep the tree they were made with
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

Odometry::Odometry(const RegistrationOptions& options) : options_(options), impl_(std::make_unique<Impl>()) {
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
  for (const auto& c : impl_->recent) timed_points += c.sensor.points.size() + c.centroids.points.size();
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

Odometry::Step Odometry::add(const cloud::Cloud& cloud, double cloud_time_s) {
  const auto& poses = trajectory_.poses();
  if (!poses.empty() && !(cloud_time_s > poses.back().time_s)) {
    throw std::invalid_argument("Odometry::add: cloud time " + std::to_string(cloud_time_s) +
                                " s is not after the previous cloud's " + std::to_string(poses.back().time_s) + " s");
  }
  if (options_.map_at_prior && prior_.empty()) {
    throw std::logic_error("Odometry::add: RegistrationOptions::map_at_prior needs a motion prior (set_motion_prior)");
  }
  const auto start = Clock::now();
  Impl& m = *impl_;
  // From here on every registration, window and re-anchoring uses the settled scale.
  if (options_.settled_robust_scale2 > 0.0 && static_cast<int>(poses.size()) == options_.settled_from_cloud) {
    options_.robust_scale2 = options_.settled_robust_scale2;
  }
  // kRobust and kGeneralized share GICP's covariances and local map.
  const bool generalized = options_.backend != IcpBackend::kPointToPoint;
  const bool robust = options_.backend == IcpBackend::kRobust;
  auto velocity_between = [](const TimedPose& a, const TimedPose& b) { return core::from_vector6(twist_between(a, b)); };
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
  const TimedPoints centroids =
      sensor_voxels(cloud, options_.source_voxel_m, options_.min_range_m, options_.max_range_m);
  const bool with_prior = !prior_.empty();
  XyzCloud::Ptr source;
  if (with_prior) {
    const Eigen::Isometry3d T_start_frame = prior_.pose_at(cloud_time_s).inverse();
    source = deskew_points(centroids, [&](double tau_s) { return T_start_frame * prior_.pose_at(cloud_time_s + tau_s); });
    if (!poses.empty()) {
      const TimedPose& from = options_.map_at_prior ? poses.front() : poses.back();
      predicted = from.T_world_lidar * prior_.pose_at(from.time_s).inverse() * prior_.pose_at(cloud_time_s);
    }
  } else {
    source = deskew_points(centroids, motion_per_s);
  }
  Eigen::Isometry3d deskewed_by = motion_per_s;  // the velocity `source` is de-skewed with (no prior)
  std::shared_ptr<Covariances> source_covariances;
  const bool smooth_start = !with_prior && generalized && options_.start_up_clouds > 0;
  if (smooth_start && static_cast<int>(poses.size()) < options_.start_up_clouds) {
    m.start_up.push_back({poses.empty() ? 0.0 : cloud_time_s - poses.front().time_s, centroids, nullptr});
  }

  Step step;
  step.T_world_lidar = predicted;
  if (!with_prior && poses.size() == 1 && m.have_first) {
    // Second cloud: no velocity yet, and the first cloud in the map is skewed by the very
    // motion being estimated. Iterate to the fixed point where the velocity that de-skews
    // both clouds is the one their registration measures.
    const TimedPose first = poses.front();
    Eigen::Isometry3d velocity = Eigen::Isometry3d::Identity();
    for (int iteration = 0; iteration < kInitIterations; ++iteration) {
      auto map = std::make_shared<XyzCloud>();
      pcl::transformPointCloud(*deskew_points(m.first_cloud, velocity), *map, first.T_world_lidar.matrix().cast<float>());
      source = deskew_points(centroids, velocity);
      const RegistrationResult r = register_clouds(source, map, step.T_world_lidar, options_);
      const double change = core::translation_error_m(r.T_target_source, step.T_world_lidar);
      step.registration = r;
      step.T_world_lidar = r.T_target_source;
      velocity = velocity_between(first, {cloud_time_s, step.T_world_lidar});
      if (iteration > 0 && change < 1e-3) break;
    }
    step.registered = true;
    source = deskew_points(centroids, velocity);
    deskewed_by = velocity;
    auto first_world = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*deskew_points(m.first_cloud, velocity), *first_world,
                             first.T_world_lidar.matrix().cast<float>());
    m.recent.front().points_world = first_world;
    if (generalized) m.recent.front().covariances_world = m.gicp.covariances_of(first_world);
    m.first_cloud = {};
    m.have_first = false;
  } else if (m.map && !m.map->empty()) {
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
    std::vector<NearestKept> kept(robust ? centroids.points.size() : 0);
    bool coarse = robust;
    RegistrationOptions coarse_options = options_;
    coarse_options.robust_scale2 = m.loose_robust_scale2;
    auto run = [&](auto& icp, const Eigen::Isometry3d& guess, RegistrationResult& r) {
      if (robust) {
        r = robust_gicp(*source, *source_covariances, *m.map, *m.map_tree, m.map_covariances, guess,
                        coarse ? coarse_options : options_, &kept, coarse);
        return;
      }
      icp.setInputSource(source);
      if constexpr (std::is_same_v<std::decay_t<decltype(icp)>, CovarianceGicp>) {
        icp.setSourceCovariances(source_covariances);  // after setInputSource, which resets them
      }
      align(icp, source, guess, r);
    };
    if (generalized) source_covariances = m.gicp.covariances_of(source);
    RegistrationResult& r = step.registration;
    r.target_points = m.map->size();
    generalized ? run(m.gicp, predicted, r) : run(m.icp, predicted, r);
    const int first_iterations = r.iterations;
    step.registered = true;
    // The registration measured this cloud's motion since the previous one: de-skew with
    // that velocity and refine (the prediction is off whenever the cart accelerates). The
    // covariances stay: the two de-skews differ by the acceleration over one tilt, which
    // moves neighbouring centroids alike.
    // When the prediction was right to within refine_above_m, so was the velocity and the
    // de-skew error is below that at the tilt's end: no second run.
    const Eigen::Isometry3d correction = predicted.inverse() * r.T_target_source;
    constexpr double lever_m = 10.0;  // a rotation error seen at 10 m
    if (!with_prior && correction.translation().norm() + lever_m * Eigen::AngleAxisd(correction.linear()).angle() >
                           options_.refine_above_m) {
      const Eigen::Isometry3d measured = velocity_between(poses.back(), {cloud_time_s, r.T_target_source});
      source = deskew_points(centroids, measured);
      deskewed_by = measured;
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
  trajectory_.push_back({cloud_time_s, step.T_world_lidar});

  // The cloud joins the local map in the world frame, its covariances rotated with it.
  const Eigen::Isometry3d& T_world_map_cloud = options_.map_at_prior ? predicted : step.T_world_lidar;
  Impl::MapCloud entry;
  entry.points_world = std::make_shared<XyzCloud>();
  pcl::transformPointCloud(*source, *entry.points_world, T_world_map_cloud.matrix().cast<float>());
  if (generalized && (poses.size() > 1 || with_prior)) {
    if (!source_covariances) source_covariances = m.gicp.covariances_of(source);
    const Eigen::Matrix3d R = T_world_map_cloud.linear();
    entry.covariances_world = std::make_shared<Covariances>(source_covariances->size());
    for (std::size_t i = 0; i < source_covariances->size(); ++i) {
      (*entry.covariances_world)[i] = R * (*source_covariances)[i] * R.transpose();
    }
  }
  if (!m.anchor.points.empty()) {
    entry.sensor = centroids;
    entry.time_s = cloud_time_s;
  }
  if (options_.window_clouds > 0 && !with_prior && generalized) {
    entry.centroids = centroids;
    entry.start_s = cloud_time_s;
    const double duration_s = centroids.t_s.empty() ? 0.0 : *std::max_element(centroids.t_s.begin(), centroids.t_s.end());
    entry.end_s = cloud_time_s + duration_s;
    entry.T_world_end = step.T_world_lidar * core::from_vector6(core::to_vector6(deskewed_by) * duration_s);
  }
  entry.serial = ++m.serial;
  m.recent.push_back(entry);
  if (poses.size() == 1 && !with_prior) {
    m.first_cloud = centroids;
    m.have_first = true;
    if (options_.reanchor_first_cloud) m.anchor = centroids;
  }
  while (static_cast<int>(m.recent.size()) > options_.local_map_clouds) m.recent.pop_front();

  const bool window = options_.window_clouds > 0 && !with_prior && generalized &&
                      static_cast<int>(poses.size()) >= options_.window_start_clouds &&
                      static_cast<int>(m.recent.size()) > options_.window_clouds &&
                      (static_cast<int>(poses.size()) - options_.window_start_clouds) % options_.window_interval_clouds == 0;
  // The window rebuilds the target itself, from the clouds it moved.
  // Between windows the merged map is not merged anew: the new cloud joins it as it is.
  if ((poses.size() >= 2 || with_prior) && !window) {
    m.rebuild_target(options_.backend, options_.merged_local_map_m, window_.solves > 0);
  }
  if (smooth_start && static_cast<int>(poses.size()) == options_.start_up_clouds) smooth_start_up();
  if (window) refine_window();
  if (!with_prior && options_.reanchor_first_cloud && !m.anchor.points.empty() &&
      static_cast<int>(poses.size()) == std::max(options_.local_map_clouds, 3) + 1) {
    reanchor_first_cloud();
  }
  step.registration.time_ms = ms_since(start);
  return step;
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
  const CurveResult r =
      solve_curve(clouds, T_world_first, fit_curve(samples, false), false, nullptr, m.gicp, options_);
  start_up_.time_ms = ms_since(start);
  start_up_.attempted = true;
  start_up_.converged = r.converged;
  start_up_.iterations = r.iterations;
  if (!r.converged) return;
  std::vector<TimedPose> moved = poses;
  double largest_move_m = 0.0;
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    moved[k].T_world_lidar = T_world_first * core::from_vector6(curve_vector(r.coefficients, clouds[k].tau_s));
    largest_move_m = std::max(largest_move_m, core::translation_error_m(moved[k].T_world_lidar, poses[k].T_world_lidar));
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
      entry.T_world_end = T_world_first * core::from_vector6(curve_vector(r.coefficients, entry.end_s - poses.front().time_s));
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
    clouds.push_back({entry.start_s - m.recent[first_entry].start_s, entry.centroids, entry.covariances_world});
    // The guess: through each cloud's poses at its start and end as it is placed now.
    samples.emplace_back(clouds.back().tau_s, base.inverse() * poses[first_pose + i].T_world_lidar);
    samples.emplace_back(entry.end_s - m.recent[first_entry].start_s, base.inverse() * entry.T_world_end);
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
    if (static_cast<int>(fixed_points->size()) < options_.covariance_neighbours) {  // nothing to hold on to
      m.rebuild_target(options_.backend, options_.merged_local_map_m);
      return;
    }
  }
  auto fixed_tree = std::make_shared<MapTree>();
  fixed_tree->setInputCloud(fixed_points);
  const TargetCovariances fixed_covariances =
      options_.merged_local_map_m > 0.0 ? TargetCovariances(fixed_points, fixed_tree, options_.covariance_neighbours)
                                        : TargetCovariances(concatenated);
  const FixedMap fixed{*fixed_points, fixed_covariances, *fixed_tree};
  const CurveResult r = solve_curve(clouds, base, fit_curve(samples, true), true, &fixed, m.gicp, options_);
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
    moved[first_pose + i].T_world_lidar = base * core::from_vector6(curve_vector(r.coefficients, clouds[i].tau_s));
    m.recent[first_entry + i].points_world = r.world[i];
    m.recent[first_entry + i].T_world_end = base * core::from_vector6(curve_vector(
        r.coefficients, m.recent[first_entry + i].end_s - m.recent[first_entry].start_s));
    // Covariances: the newest cloud's anew, from where the curve puts its points (its
    // registration de-skewed it with a constant velocity: centimetres off at its far end);
    // the others' turn with their cloud. With a window after every tilt the others' were so
    // computed when they were newest; keeping the registration's for the newest too then
    // gave 11.8 against 10.5 mm mean aligned error on the 14 sim streets of docs/mapping.md.
    // With a window every 3rd tilt and the merged map, no cloud enters a second window: the
    // newest's serve only until the next window merges it into the fixed part, where the
    // merged points get their own; they are the registration's, turned (the 14 streets'
    // errors in RegistrationOptions::accurate()'s comment were measured so).
    const bool used_again =
        options_.window_interval_clouds < options_.window_clouds || options_.merged_local_map_m == 0.0;
    if (i + 1 == w && used_again) {
      m.recent[first_entry + i].covariances_world = m.gicp.covariances_of(r.world[i]);
      continue;
    }
    const Eigen::Matrix3d turn =
        moved[first_pose + i].T_world_lidar.linear() * poses[first_pose + i].T_world_lidar.linear().transpose();
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
  const core::Vector6d twist = 2.0 * twist_between(poses[1], poses[2]) - twist_between(poses[2], poses[3]);
  const XyzCloud::Ptr source = deskew_points(anchor, core::from_vector6(twist));
  // The clouds of the local map were de-skewed with the velocity known when each came; the
  // first of them with the start-up guess. De-skew them again along the trajectory as it
  // now stands (covariances kept: the change is below a voxel's extent).
  for (auto& c : m.recent) {
    if (c.sensor.points.empty()) continue;
    const Eigen::Isometry3d T_world_start = trajectory_.pose_at(c.time_s);
    const Eigen::Isometry3d T_start_world = T_world_start.inverse();
    const XyzCloud::Ptr in_start = deskew_points(
        c.sensor, [&](double tau_s) { return T_start_world * trajectory_.pose_at(c.time_s + tau_s); });
    auto points = std::make_shared<XyzCloud>();
    pcl::transformPointCloud(*in_start, *points, T_world_start.matrix().cast<float>());
    c.points_world = points;
    c.sensor = {};
  }
  m.rebuild_target(options_.backend, options_.merged_local_map_m);
  const Eigen::Isometry3d& before = poses.front().T_world_lidar;
  RegistrationResult r;
  if (options_.backend == IcpBackend::kRobust) {
    r = robust_gicp(*source, *m.gicp.covariances_of(source), *m.map, *m.map_tree, m.map_covariances, before,
                    options_);
  } else {
    r = register_clouds(source, m.map, before, options_);
  }
  // The world frame in which the first cloud keeps its pose: W' = C W.
  const Eigen::Isometry3d C = before * r.T_target_source.inverse();
  reanchoring_.attempted = true;
  reanchoring_.registration = r;
  reanchoring_.correction = C;
  // A correction beyond the correspondence gate is not a refinement: keep the start.
  if (!r.converged || (r.T_target_source.translation() - before.translation()).norm() > options_.max_correspondence_m) {
    return;
  }
  reanchoring_.applied = true;
  std::vector<TimedPose> moved;
  moved.reserve(poses.size());
  moved.push_back(poses.front());  // C r = before: the first cloud stays where the map starts
  for (std::size_t k = 1; k < poses.size(); ++k) moved.push_back({poses[k].time_s, C * poses[k].T_world_lidar});
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
