// The trajectory of a few clouds as one smooth curve, solved against itself and a fixed map
// (registration_internal.hpp: solve_curve).
#include "registration_internal.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

namespace rgbdt::rgbdt_map::detail {

core::Vector6d curve_vector(const CurveCoefficients& c, double tau_s) {
  return c.segment<6>(0) +
         tau_s * (c.segment<6>(6) + tau_s * (c.segment<6>(12) + tau_s * c.segment<6>(18)));
}

namespace {

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
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
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
  void add(const PointDerivative& a, const PointDerivative* b, const Eigen::Matrix3d& M,
           const Eigen::Vector3d& r, double scale2) {
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
        H.block<6, 6>(6 * k, 6 * l) =
            moment_[k + l] + cross_[4 * k + l] + cross_[4 * l + k].transpose();
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

}  // namespace

CurveCoefficients fit_curve(const std::vector<std::pair<double, Eigen::Isometry3d>>& poses,
                            bool free_offset) {
  const int first = free_offset ? 0 : 1;
  Eigen::MatrixXd A =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(poses.size()) * 6, (4 - first) * 6);
  Eigen::VectorXd b(static_cast<Eigen::Index>(poses.size()) * 6);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const auto row = static_cast<Eigen::Index>(k) * 6;
    for (int power = first; power < 4; ++power) {
      A.block<6, 6>(row, (power - first) * 6) =
          std::pow(poses[k].first, power) * Eigen::Matrix<double, 6, 6>::Identity();
    }
    b.segment<6>(row) = core::to_vector6(poses[k].second);
  }
  CurveCoefficients c = CurveCoefficients::Zero();
  c.tail((4 - first) * 6) = A.colPivHouseholderQr().solve(b);
  return c;
}

namespace {

/// The latest point time of the clouds after the first cloud's start: the curve's span.
double curve_span(const std::vector<CurveCloud>& clouds) {
  double tau_max = 0.0;
  for (const auto& c : clouds) {
    for (float t : c.sensor.t_s) tau_max = std::max(tau_max, c.tau_s + t);
  }
  return tau_max;
}

/// Each cloud's points placed along the curve c, each at the pose at its own time.
std::vector<XyzCloud::Ptr> place_on_curve(const std::vector<CurveCloud>& clouds,
                                          const Eigen::Isometry3d& base,
                                          const CurveCoefficients& c) {
  std::vector<XyzCloud::Ptr> world(clouds.size());
  for (std::size_t i = 0; i < clouds.size(); ++i) {
    const double tau0 = clouds[i].tau_s;
    world[i] = deskew_points(clouds[i].sensor, [&c, &base, tau0](double t) {
      return Eigen::Isometry3d(base * core::from_vector6(curve_vector(c, tau0 + t)));
    });
  }
  return world;
}

/// Each cloud's GICP covariances in the world: its own when given, else those of its
/// points as the guess places them.
std::vector<std::shared_ptr<const Covariances>> world_covariances(
    const std::vector<CurveCloud>& clouds, const Eigen::Isometry3d& base,
    const CurveCoefficients& guess, CovarianceGicp& gicp) {
  std::vector<std::shared_ptr<const Covariances>> covariances(clouds.size());
  std::vector<XyzCloud::Ptr> guessed;
  for (std::size_t i = 0; i < clouds.size(); ++i) {
    covariances[i] = clouds[i].covariances_world;
    if (covariances[i]) continue;
    if (guessed.empty()) guessed = place_on_curve(clouds, base, guess);
    covariances[i] = gicp.covariances_of(guessed[i]);
  }
  return covariances;
}

/// Each point's derivative by the from_vector6 parameters at its time (the 24
/// coefficients scale it by 1, tau, tau^2, tau^3): [-[y]x R_base J_l(w), R_base] with
/// y = R_base R(w) x. R(w) and R_base J_l(w) are shared by a 1 ms bin, as in
/// place_on_curve.
std::vector<std::vector<PointDerivative>> point_derivatives(const std::vector<CurveCloud>& clouds,
                                                            const Eigen::Matrix3d& R_base,
                                                            const CurveCoefficients& c) {
  std::vector<std::vector<PointDerivative>> derivative(clouds.size());
  for (std::size_t i = 0; i < clouds.size(); ++i) {
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
  return derivative;
}

/// The clouds of one Gauss-Newton step: placed on the curve, with their points' derivatives.
struct PlacedClouds {
  std::vector<XyzCloud::Ptr> world;
  std::vector<std::vector<PointDerivative>> derivative;
};

/// The GICP terms of the curve's points, renewed every step: each point against its nearest
/// point of the other clouds on the curve and of the fixed map, within the gate. The
/// nearest are kept across the steps (NearestKept) and searched anew only when the points'
/// moves since do not prove them.
class CurveCorrespondences {
 public:
  CurveCorrespondences(const std::vector<CurveCloud>& clouds, const FixedMap* fixed,
                       std::vector<std::shared_ptr<const Covariances>> covariances,
                       const RegistrationOptions& options)
      : n_(clouds.size()),
        fixed_(fixed),
        covariances_(std::move(covariances)),
        gate2_(options.max_correspondence_m * options.max_correspondence_m),
        robust_scale2_(options.robust_scale2),
        kept_others_(n_),
        kept_fixed_(n_),
        moved_(n_, 0.0f),
        others_tree_(n_),
        others_tree_moved_(n_, 0.0f) {
    for (std::size_t i = 0; i < n_; ++i) {
      kept_others_[i].resize(clouds[i].sensor.points.size());
      kept_fixed_[i].resize(clouds[i].sensor.points.size());
    }
  }

  /// How far the points moved since the previous step: bounds for the kept neighbours.
  void record_move(const std::vector<XyzCloud::Ptr>& world) {
    for (std::size_t i = 0; i < n_; ++i) {
      float largest = 0.0f;
      if (!previous_.empty()) {
        for (std::size_t p = 0; p < world[i]->size(); ++p) {
          largest = std::max(
              largest,
              ((*world[i])[p].getVector3fMap() - (*previous_[i])[p].getVector3fMap()).norm());
        }
      }
      moved_[i] += largest;
    }
    previous_ = world;
  }

  /// Every point's terms added to `normal`; the number of terms (inliers).
  std::size_t add_terms(const PlacedClouds& placed, CurveNormalEquations& normal) {
    std::size_t inliers = 0;
    for (std::size_t i = 0; i < n_; ++i) inliers += add_cloud_terms(i, placed, normal);
    return inliers;
  }

 private:
  /// The terms of cloud i's points.
  std::size_t add_cloud_terms(std::size_t i, const PlacedClouds& placed,
                              CurveNormalEquations& normal) {
    const std::vector<XyzCloud::Ptr>& world = placed.world;
    // The other clouds on the curve, in order (their tree: others_tree_[i]).
    std::vector<std::size_t> offset(n_, 0);
    std::size_t others_size = 0;
    float others_moved = 0.0f;  // a bound on how far any of their points moved since the first step
    for (std::size_t j = 0; j < n_; ++j) {
      if (j == i) continue;
      offset[j] = others_size;
      others_size += world[j]->size();
      others_moved += moved_[j];
    }
    auto search_others = [&](const pcl::PointXYZ& query, std::vector<int>& index,
                             std::vector<float>& distance2, int k) {
      if (!others_tree_[i]) {
        auto others = std::make_shared<XyzCloud>();
        for (std::size_t j = 0; j < n_; ++j) {
          if (j != i) *others += *world[j];
        }
        others_tree_[i] = std::make_unique<MapTree>();
        others_tree_[i]->setInputCloud(others);
        others_tree_moved_[i] = others_moved;
      }
      return others_tree_[i]->nearestKSearch(query, k, index, distance2);
    };
    auto owner = [&](std::size_t k) {  // (cloud, point) of a point of `others`
      std::size_t j = 0;
      while (j == i || k >= offset[j] + world[j]->size()) ++j;
      return std::make_pair(j, k - offset[j]);
    };
    auto others_position = [&](std::size_t k) {
      const auto [j, q] = owner(k);
      return (*world[j])[q].getVector3fMap();
    };
    std::size_t inliers = 0;
    for (std::size_t p = 0; p < world[i]->size(); ++p) {
      const pcl::PointXYZ& query = (*world[i])[p];
      const PointDerivative& a = placed.derivative[i][p];
      std::size_t k = kept_others_[i][p].nearest_in_stale(query, others_moved, search_others,
                                                          others_position, others_tree_moved_[i]);
      if (k == NearestKept::kStale) {  // the tree is too old to tell: build it anew
        others_tree_[i].reset();
        k = kept_others_[i][p].nearest_in_stale(query, others_moved, search_others, others_position,
                                                others_tree_moved_[i]);
      }
      if (k != NearestKept::kNone) {
        const auto [j, q] = owner(k);
        const Eigen::Vector3d r =
            (query.getVector3fMap() - (*world[j])[q].getVector3fMap()).cast<double>();
        if (r.squaredNorm() <= gate2_) {
          const Eigen::Matrix3d M = ((*covariances_[i])[p] + (*covariances_[j])[q]).inverse();
          normal.add(a, &placed.derivative[j][q], M, r, robust_scale2_);
          ++inliers;
        }
      }
      if (fixed_) inliers += add_fixed_term(i, p, query, a, normal);
    }
    return inliers;
  }

  /// The term of point p of cloud i against the fixed map: 1 when added, else 0.
  std::size_t add_fixed_term(std::size_t i, std::size_t p, const pcl::PointXYZ& query,
                             const PointDerivative& a, CurveNormalEquations& normal) {
    const FixedMap* fixed = fixed_;
    auto search_fixed = [&fixed](const pcl::PointXYZ& at, std::vector<int>& index,
                                 std::vector<float>& distance2, int k) {
      return fixed->tree.nearestKSearch(at, k, index, distance2);
    };
    auto fixed_position = [&fixed](std::size_t k) { return fixed->points[k].getVector3fMap(); };
    const std::size_t f = kept_fixed_[i][p].nearest(query, 0.0f, search_fixed, fixed_position);
    if (f == NearestKept::kNone) return 0;
    const Eigen::Vector3d r =
        (query.getVector3fMap() - fixed->points[f].getVector3fMap()).cast<double>();
    if (r.squaredNorm() > gate2_) return 0;
    const Eigen::Matrix3d M = ((*covariances_[i])[p] + fixed->covariances[f]).inverse();
    normal.add(a, nullptr, M, r, robust_scale2_);
    return 1;
  }

  std::size_t n_;
  const FixedMap* fixed_;
  std::vector<std::shared_ptr<const Covariances>> covariances_;
  double gate2_, robust_scale2_;
  std::vector<std::vector<NearestKept>> kept_others_, kept_fixed_;
  std::vector<float> moved_;  ///< per cloud, the sum over steps of its points' largest move
  // Per cloud, a search tree of the other clouds, kept across the steps (built when a point
  // first needs a search, and anew only when NearestKept cannot tell the nearest from it:
  // the clouds move by millimetres per step after the first), and their move bound then.
  std::vector<std::unique_ptr<MapTree>> others_tree_;
  std::vector<float> others_tree_moved_;
  std::vector<XyzCloud::Ptr> previous_;  ///< the clouds as the previous step placed them
};

/// The Gauss-Newton step of the coefficients from the normal equations. Once a step moves
/// no pose by more than 30x the epsilons (3 mm and 3e-3 rad), the steps after it keep its
/// H (factorised) and accumulate g alone: the minimum is where g = 0 whatever H, and there
/// the correspondences barely change from step to step, nor H with them. A term of g costs
/// ~1/15 of the multiplications of its H. On sim street seed 1 (--accurate) 103 of the 191
/// steps of the windows and the start-up kept H, the steps per window stayed 4.5, and the
/// 14 streets of docs/mapping.md each moved by <= 0.2 mm (mean anchored error 0.0291 m
/// both). Kept from 100x on (after the first step), the steps per window went from 4.5 to
/// 6.5.
class CurveStep {
 public:
  explicit CurveStep(bool free_offset) : free_offset_(free_offset) {}

  /// Whether this step keeps the last H (the normal equations then accumulate g alone).
  bool keeps_hessian() const { return factored_ && small_step_; }

  /// The step: -H^-1 g, c0 held at 0 unless the offset is free.
  CurveCoefficients solve(const CurveNormalEquations& normal) {
    Eigen::Matrix<double, 24, 1> g;
    if (keeps_hessian()) {
      normal.assemble_gradient(g);
    } else {
      Eigen::Matrix<double, 24, 24> H;
      normal.assemble(H, g);
      if (!free_offset_) {  // c0 stays 0: solve for the other coefficients only
        H.topRows<6>().setZero();
        H.leftCols<6>().setZero();
        H.topLeftCorner<6, 6>().setIdentity();
      }
      factor_.compute(H);
      factored_ = true;
    }
    if (!free_offset_) g.head<6>().setZero();
    return -factor_.solve(g);
  }

  /// The size of the step just taken decides whether the next keeps H.
  void took(double step_m, double step_rad, const RegistrationOptions& options) {
    small_step_ = step_m < kKeepHessianBelow * options.translation_epsilon_m &&
                  step_rad < kKeepHessianBelow * options.rotation_epsilon_rad;
  }

 private:
  static constexpr double kKeepHessianBelow = 30.0;
  bool free_offset_;
  Eigen::LDLT<Eigen::Matrix<double, 24, 24>> factor_;
  bool factored_ = false, small_step_ = false;
};

/// A step's largest effect on a pose over the span [0, tau_max]: translation [m] and
/// rotation [rad].
struct PoseChange {
  double m = 0.0, rad = 0.0;
};

PoseChange largest_change(const CurveCoefficients& delta, double tau_max) {
  PoseChange change;
  for (int k = 0; k <= 10; ++k) {
    const core::Vector6d d = curve_vector(delta, tau_max * k / 10.0);
    change.rad = std::max(change.rad, d.head<3>().norm());
    change.m = std::max(change.m, d.tail<3>().norm());
  }
  return change;
}

}  // namespace

CurveResult solve_curve(const std::vector<CurveCloud>& clouds, const Eigen::Isometry3d& base,
                        const CurveCoefficients& guess, bool free_offset, const FixedMap* fixed,
                        CovarianceGicp& gicp, const RegistrationOptions& options) {
  CurveResult result;
  result.coefficients = guess;
  const double tau_max = curve_span(clouds);
  CurveCorrespondences correspondences(clouds, fixed, world_covariances(clouds, base, guess, gicp),
                                       options);
  const Eigen::Matrix3d R_base = base.linear();
  CurveStep step(free_offset);
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const CurveCoefficients c = result.coefficients;
    PlacedClouds placed;
    placed.world = place_on_curve(clouds, base, c);
    placed.derivative = point_derivatives(clouds, R_base, c);
    correspondences.record_move(placed.world);
    CurveNormalEquations normal(step.keeps_hessian());
    if (correspondences.add_terms(placed, normal) < 24) break;
    const CurveCoefficients delta = step.solve(normal);
    result.coefficients += delta;
    result.iterations = iteration + 1;
    const PoseChange change = largest_change(delta, tau_max);
    if (change.m < options.translation_epsilon_m && change.rad < options.rotation_epsilon_rad) {
      result.converged = true;
      break;
    }
    step.took(change.m, change.rad, options);
  }
  result.world = place_on_curve(clouds, base, result.coefficients);
  return result;
}

}  // namespace rgbdt::rgbdt_map::detail
