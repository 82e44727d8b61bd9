#include "rgbdt/extrinsics/covariance.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "covariance_input.hpp"

namespace rgbdt::extrinsics {

namespace {

/// Two unit vectors spanning the plane orthogonal to the unit vector n.
void plane_axes(const Eigen::Vector3d& n, Eigen::Vector3d* a1, Eigen::Vector3d* a2) {
  const Eigen::Vector3d helper =
      std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *a1 = n.cross(helper).normalized();
  *a2 = n.cross(*a1);
}

/// Normal of the least-squares plane through the points (smallest principal direction).
Eigen::Vector3d principal_normal(const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<std::size_t>& index, Eigen::Vector3d* mean) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (std::size_t i : index) m += points[i];
  m /= static_cast<double>(std::max<std::size_t>(1, index.size()));
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t i : index) scatter += (points[i] - m) * (points[i] - m).transpose();
  *mean = m;
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
}

struct HoleCircle {
  Eigen::Vector3d center, normal;
  std::vector<std::size_t> points;  // indices into the view's circle points
};

/// The view's circle points grouped by hole: by the nearest of lidar_centers when the view
/// has them, else by the gaps between consecutive points (a hole's circle is sampled at a
/// fixed small step, so the step to the next hole's first point is much longer).
std::vector<HoleCircle> split_holes(const TargetView& view) {
  const auto& p = view.lidar_circle_points;
  std::vector<HoleCircle> holes;
  if (!view.lidar_centers.empty()) {
    for (const auto& c : view.lidar_centers) holes.push_back({c, Eigen::Vector3d::Zero(), {}});
    for (std::size_t i = 0; i < p.size(); ++i) {
      std::size_t best = 0;
      for (std::size_t h = 1; h < holes.size(); ++h)
        if ((p[i] - holes[h].center).squaredNorm() < (p[i] - holes[best].center).squaredNorm()) best = h;
      holes[best].points.push_back(i);
    }
  } else if (!p.empty()) {
    std::vector<double> steps;
    for (std::size_t i = 1; i < p.size(); ++i) steps.push_back((p[i] - p[i - 1]).norm());
    std::vector<double> sorted = steps;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double gap = sorted.empty() ? 0.0 : 3.0 * sorted[sorted.size() / 2];
    holes.push_back({});
    holes.back().points.push_back(0);
    for (std::size_t i = 1; i < p.size(); ++i) {
      if (steps[i - 1] > gap) holes.push_back({});
      holes.back().points.push_back(i);
    }
  }
  const bool given_normals = !view.lidar_centers.empty() && view.lidar_centers.size() == view.lidar_normals.size();
  for (std::size_t h = 0; h < holes.size(); ++h) {
    if (given_normals) {  // the detector's centre and normal: nothing to fit
      holes[h].normal = view.lidar_normals[h].normalized();
      continue;
    }
    Eigen::Vector3d mean;
    holes[h].normal = principal_normal(p, holes[h].points, &mean);
    if (view.lidar_centers.empty()) holes[h].center = mean;
  }
  holes.erase(std::remove_if(holes.begin(), holes.end(), [](const HoleCircle& h) { return h.points.size() < 3; }),
              holes.end());
  return holes;
}

/// Covariance of theta = (centre shift [3], tilt about a1, tilt about a2).
Eigen::Matrix<double, 5, 5> theta_covariance(const LidarHoleSigma& s, const Eigen::Vector3d& n,
                                             const Eigen::Vector3d& a1, const Eigen::Vector3d& a2) {
  Eigen::Matrix<double, 5, 5> C = Eigen::Matrix<double, 5, 5>::Zero();
  C.topLeftCorner<3, 3>() = s.center_in_plane_m * s.center_in_plane_m * (a1 * a1.transpose() + a2 * a2.transpose()) +
                            s.center_normal_m * s.center_normal_m * n * n.transpose();
  C(3, 3) = C(4, 4) = s.tilt_rad * s.tilt_rad;
  return C;
}

/// Pseudo-inverse of a symmetric positive semi-definite matrix; *full_rank false when a
/// direction's eigenvalue is below 1e-14 of the largest (as align_edges always did).
core::Matrix6d pseudo_inverse(const core::Matrix6d& H, bool* full_rank) {
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eig(H);
  const core::Vector6d& lambda = eig.eigenvalues();
  *full_rank = eig.info() == Eigen::Success && lambda(5) > 0.0;
  core::Vector6d inverse = core::Vector6d::Zero();
  for (int i = 0; i < 6 && *full_rank; ++i) {
    if (lambda(i) >= 1e-14 * lambda(5)) inverse(i) = 1.0 / lambda(i);
    else *full_rank = false;
  }
  return eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
}

/// The centre error that an edge error smooth along the hole causes, per in-plane axis
/// [m^2]: the radial residuals are fitted with the Fourier orders 0-5 around the hole, and
/// the mean square of the order 2-5 coefficients is taken as that of order 1 (the centre
/// shift, which the circle fit absorbs and so cannot be seen). Edge errors that vary slowly
/// around the hole (point density that changes across it, a scan pattern) show in the
/// orders next to 1; white edge noise gives about sigma^2 (2 / n), as the scatter term.
/// 0 when the edges are too few (< 36) or leave a quadrant around the hole empty.
double smooth_edge_error2(const std::vector<Eigen::Vector3d>& edge_points, const Eigen::Vector3d& center,
                          const Eigen::Vector3d& a1, const Eigen::Vector3d& a2) {
  constexpr int kOrders = 5, kColumns = 2 * kOrders + 1, kMinPoints = 36;
  if (edge_points.size() < static_cast<std::size_t>(kMinPoints)) return 0.0;
  Eigen::MatrixXd A(static_cast<Eigen::Index>(edge_points.size()), kColumns);
  Eigen::VectorXd b(A.rows());
  int quadrants = 0;
  Eigen::Index row = 0;
  for (const auto& p : edge_points) {
    const Eigen::Vector2d d((p - center).dot(a1), (p - center).dot(a2));
    if (d.norm() <= 0.0) continue;
    const double phi = std::atan2(d.y(), d.x());
    quadrants |= 1 << std::clamp(static_cast<int>((phi + EIGEN_PI) / (0.5 * EIGEN_PI)), 0, 3);
    A(row, 0) = 1.0;
    for (int k = 1; k <= kOrders; ++k) {
      A(row, 2 * k - 1) = std::cos(k * phi);
      A(row, 2 * k) = std::sin(k * phi);
    }
    b(row++) = d.norm();
  }
  if (row < kMinPoints || quadrants != 0xF) return 0.0;
  const Eigen::VectorXd x = A.topRows(row).colPivHouseholderQr().solve(b.head(row));
  return x.tail(2 * (kOrders - 1)).squaredNorm() / (2.0 * (kOrders - 1));
}

}  // namespace

LidarHoleSigma lidar_hole_sigma(const std::vector<Eigen::Vector3d>& edge_points,
                                const std::vector<Eigen::Vector3d>& board_points,
                                const Eigen::Vector3d& center, const Eigen::Vector3d& normal,
                                double radius_m, double edge_bias_m, double point_spacing_m) {
  if (edge_points.size() < 3 || board_points.size() < 3) {
    std::ostringstream os;
    os << "lidar_hole_sigma: " << edge_points.size() << " edge points and " << board_points.size()
       << " board points (expected >= 3 of each)";
    throw std::invalid_argument(os.str());
  }
  const Eigen::Vector3d n = normal.normalized();
  Eigen::Vector3d a1, a2;
  plane_axes(n, &a1, &a2);
  LidarHoleSigma s;
  // In-plane centre: sigma_e^2 (sum u u^T)^-1, the larger axis (edges along few scan lines
  // leave one direction weaker). sigma_e is the scatter of the radial residuals |p - c| - r
  // about their mean: a common radial offset (the beam footprint's edge bias, which the
  // detector corrects from the data, or a radius that differs from the nominal one) widens
  // or shrinks the circle without moving its centre. 3 degrees of freedom go to the centre
  // and that offset.
  Eigen::Matrix2d M = Eigen::Matrix2d::Zero();
  double sum = 0.0, sum2 = 0.0;
  std::size_t used = 0;
  for (const auto& p : edge_points) {
    const Eigen::Vector2d d((p - center).dot(a1), (p - center).dot(a2));
    const double r = d.norm();
    if (r <= 0.0) continue;
    sum += r - radius_m;
    sum2 += (r - radius_m) * (r - radius_m);
    ++used;
    M += (d / r) * (d / r).transpose();
  }
  const double n_used = static_cast<double>(std::max<std::size_t>(used, 1));
  const double scatter2 = std::max(0.0, sum2 - sum * sum / n_used);
  const double spacing = std::max(0.0, point_spacing_m);
  const double sigma_e2 = std::max(scatter2 / std::max(1.0, n_used - 3.0), spacing * spacing / 12.0);
  // Independent stretches of edge: one per footprint (or point step) around the circle.
  const double stretch = std::max(spacing, 2.0 * std::abs(edge_bias_m));
  const double independent =
      stretch > 0.0 ? std::clamp(2.0 * static_cast<double>(EIGEN_PI) * radius_m / stretch, 3.0, n_used) : n_used;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig_m(M);
  const double weakest = eig_m.eigenvalues()(0) * independent / n_used;
  // The footprint's systematic part (see the header).
  const double range = center.norm();
  const double sin_incidence =
      range > 0.0 ? std::sqrt(std::max(0.0, 1.0 - std::pow(center.dot(n) / range, 2))) : 0.0;
  const double footprint2 = std::pow(0.5 * edge_bias_m * sin_incidence, 2);
  const double smooth2 = smooth_edge_error2(edge_points, center, a1, a2);
  s.center_in_plane_m = weakest > 1e-9 ? std::sqrt(std::max(sigma_e2 / weakest, smooth2) + footprint2) : radius_m;
  // Board plane z = b0 + b1 u + b2 w in the hole's axes: offset at the centre and slopes.
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Vector3d Atz = Eigen::Vector3d::Zero();
  for (const auto& p : board_points) {
    const Eigen::Vector3d row(1.0, (p - center).dot(a1), (p - center).dot(a2));
    AtA += row * row.transpose();
    Atz += row * (p - center).dot(n);
  }
  const Eigen::Vector3d b = AtA.ldlt().solve(Atz);
  double z2 = 0.0;
  for (const auto& p : board_points) {
    const Eigen::Vector3d row(1.0, (p - center).dot(a1), (p - center).dot(a2));
    z2 += std::pow((p - center).dot(n) - row.dot(b), 2);
  }
  const double sigma_z2 = z2 / std::max<double>(1.0, static_cast<double>(board_points.size()) - 3.0);
  const Eigen::Matrix3d C = sigma_z2 * AtA.inverse();
  s.center_normal_m = std::sqrt(std::max(0.0, C(0, 0)) + footprint2);
  s.tilt_rad = std::sqrt(std::max({0.0, C(1, 1), C(2, 2)}));
  return s;
}

std::string CovarianceOptions::validate() const {
  std::ostringstream os;
  if (!(default_range_sigma_m > 0.0) || !std::isfinite(default_range_sigma_m))
    os << "default_range_sigma_m = " << default_range_sigma_m << " (expected > 0 m)";
  if (resamples < 0) os << "resamples = " << resamples << " (expected >= 0)";
  for (std::size_t v = 0; v < per_view.size() && os.str().empty(); ++v) {
    for (const LidarHoleSigma& s : per_view[v]) {
      if (!(s.center_in_plane_m >= 0.0 && s.center_normal_m >= 0.0 && s.tilt_rad >= 0.0) ||
          !std::isfinite(s.center_in_plane_m + s.center_normal_m + s.tilt_rad)) {
        os << "per_view[" << v << "]: a hole sigma is negative or not finite (" << s.center_in_plane_m << ", "
           << s.center_normal_m << ", " << s.tilt_rad << ")";
        break;
      }
    }
  }
  return os.str();
}

double nees(const core::Vector6d& error, const core::Matrix6d& covariance) {
  const Eigen::LLT<core::Matrix6d> llt(covariance);
  if (llt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return error.dot(llt.solve(error));
}

core::Matrix6d covariance_max(const core::Matrix6d& A, const core::Matrix6d& B) {
  const core::Matrix6d D = 0.5 * ((B - A) + (B - A).transpose());
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eig(D);
  const core::Vector6d positive = eig.eigenvalues().cwiseMax(0.0);
  return A + eig.eigenvectors() * positive.asDiagonal() * eig.eigenvectors().transpose();
}

namespace detail {

ViewCovarianceInput view_covariance_input(const ProjectionModel& cam, const SmoothView& field,
                                          const TargetView& view, const core::Vector6d& x,
                                          const std::vector<LidarHoleSigma>* sigma,
                                          double default_range_sigma_m) {
  const std::size_t n = view.lidar_circle_points.size();
  PointJacobians at_x;
  at_x.uv.resize(2 * n);
  at_x.r.resize(2 * n);
  at_x.J.resize(12 * n);
  ViewEdgeCost(&cam, &field, &view.lidar_circle_points, 0.0)
      .evaluate_points(x.data(), at_x.uv.data(), at_x.r.data(), at_x.J.data());
  return view_covariance_input(at_x, view, x, sigma, default_range_sigma_m);
}

ViewCovarianceInput view_covariance_input(const PointJacobians& at_x, const TargetView& view,
                                          const core::Vector6d& x,
                                          const std::vector<LidarHoleSigma>* sigma,
                                          double default_range_sigma_m) {
  ViewCovarianceInput out;
  const std::vector<HoleCircle> holes = split_holes(view);
  const std::vector<double>&uv = at_x.uv, &r = at_x.r, &J = at_x.J;
  const Eigen::Matrix3d R = core::from_vector6(x).linear();
  const bool caller_sigma = sigma != nullptr && sigma->size() == holes.size();
  for (std::size_t h = 0; h < holes.size(); ++h) {
    const HoleCircle& hole = holes[h];
    Eigen::Vector3d a1, a2;
    plane_axes(hole.normal, &a1, &a2);
    core::Vector6d score = core::Vector6d::Zero();
    // B = sum_i J_i^T (d r_i / d p_lidar) (d p / d theta) with d r / d p_lidar = (d r / d t) R
    // and d p / d theta = [I, a1 x d, a2 x d]: sum_i P_i [R, R (a1 x d_i), R (a2 x d_i)],
    // P_i = J_i^T (d r_i / d t) the last three columns of J_i^T J_i. The first three columns
    // of B are then (sum_i P_i) R, and R (a x d) = (R a) x (R d).
    core::Matrix6d hole_JtJ = core::Matrix6d::Zero();
    Eigen::Matrix<double, 6, 2> B_tilt = Eigen::Matrix<double, 6, 2>::Zero();
    const Eigen::Vector3d Ra1 = R * a1, Ra2 = R * a2;
    double radius = 0.0;
    for (std::size_t i : hole.points) {
      if (!std::isfinite(uv[2 * i]) || !std::isfinite(uv[2 * i + 1])) continue;
      const Eigen::Map<const Eigen::Matrix<double, 2, 6, Eigen::RowMajor>> Ji(J.data() + 12 * i);
      const Eigen::Map<const Eigen::Vector2d> ri(r.data() + 2 * i);
      const core::Matrix6d JtJ_i = Ji.transpose() * Ji;
      hole_JtJ += JtJ_i;
      out.r2 += ri.squaredNorm();
      ++out.count;
      score += Ji.transpose() * ri;
      const Eigen::Vector3d d = view.lidar_circle_points[i] - hole.center;
      radius += d.norm();
      const Eigen::Vector3d Rd = R * d;
      B_tilt.col(0) += JtJ_i.rightCols<3>() * Ra1.cross(Rd);
      B_tilt.col(1) += JtJ_i.rightCols<3>() * Ra2.cross(Rd);
    }
    out.JtJ += hole_JtJ;
    Eigen::Matrix<double, 6, 5> B;
    B << hole_JtJ.rightCols<3>() * R, B_tilt;
    radius /= static_cast<double>(std::max<std::size_t>(1, hole.points.size()));
    LidarHoleSigma s;
    if (caller_sigma) {
      s = (*sigma)[h];
      ++out.holes_with_sigma;
    } else {
      s.center_in_plane_m = s.center_normal_m = default_range_sigma_m;
      s.tilt_rad = radius > 0.0 ? default_range_sigma_m / radius : 0.0;
    }
    out.hole_scores.push_back(score);
    out.hole_systematic.push_back(B * theta_covariance(s, hole.normal, a1, a2) * B.transpose());
  }
  return out;
}

std::vector<Eigen::Vector3d> perturbed_circle_points(const TargetView& view,
                                                     const std::vector<LidarHoleSigma>* sigma,
                                                     double default_range_sigma_m, std::mt19937_64* rng) {
  std::vector<Eigen::Vector3d> out = view.lidar_circle_points;
  const std::vector<HoleCircle> holes = split_holes(view);
  const bool caller_sigma = sigma != nullptr && sigma->size() == holes.size();
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (std::size_t h = 0; h < holes.size(); ++h) {
    const HoleCircle& hole = holes[h];
    Eigen::Vector3d a1, a2;
    plane_axes(hole.normal, &a1, &a2);
    LidarHoleSigma s;
    if (caller_sigma) {
      s = (*sigma)[h];
    } else {
      double radius = 0.0;
      for (std::size_t i : hole.points) radius += (out[i] - hole.center).norm();
      radius /= static_cast<double>(hole.points.size());
      s.center_in_plane_m = s.center_normal_m = default_range_sigma_m;
      s.tilt_rad = radius > 0.0 ? default_range_sigma_m / radius : 0.0;
    }
    const Eigen::Vector3d shift = s.center_in_plane_m * (gauss(*rng) * a1 + gauss(*rng) * a2) +
                                  s.center_normal_m * gauss(*rng) * hole.normal;
    const Eigen::Vector3d tilt = s.tilt_rad * (gauss(*rng) * a1 + gauss(*rng) * a2);
    const Eigen::Matrix3d R = core::rotation_from_vector(tilt);
    for (std::size_t i : hole.points) out[i] = hole.center + shift + R * (out[i] - hole.center);
  }
  return out;
}

CovarianceTerms combine_covariance(const std::vector<ViewCovarianceInput>& views,
                                   const std::vector<core::Vector6d>& leave_one_out,
                                   const std::vector<core::Vector6d>& resampled_deviations) {
  CovarianceTerms t;
  core::Matrix6d H = core::Matrix6d::Zero(), S = core::Matrix6d::Zero(), Sys = core::Matrix6d::Zero();
  double r2 = 0.0;
  std::size_t count = 0;
  for (const ViewCovarianceInput& v : views) {
    H += v.JtJ;
    r2 += v.r2;
    count += v.count;
    for (const auto& s : v.hole_scores) S += s * s.transpose();
    for (const auto& b : v.hole_systematic) Sys += b;
    t.num_holes += static_cast<int>(v.hole_scores.size());
    t.holes_with_sigma += v.holes_with_sigma;
  }
  t.num_views = static_cast<int>(views.size());
  if (count <= 6) return t;
  const core::Matrix6d Hinv = pseudo_inverse(H, &t.valid);
  t.jacobian = Hinv * (r2 / static_cast<double>(count - 6));
  const double G = t.num_holes;
  t.sandwich = G >= 2 ? covariance_max(t.jacobian, (G / (G - 1.0)) * Hinv * S * Hinv) : t.jacobian;
  t.systematic = Hinv * Sys * Hinv;
  t.total = t.sandwich + t.systematic;
  const std::size_t V = leave_one_out.size();
  if (V >= 3) {
    core::Vector6d mean = core::Vector6d::Zero();
    for (const auto& x : leave_one_out) mean += x;
    mean /= static_cast<double>(V);
    for (const auto& x : leave_one_out) t.jackknife += (x - mean) * (x - mean).transpose();
    t.jackknife *= static_cast<double>(V - 1) / static_cast<double>(V);
    t.jackknife_used = true;
    t.total = covariance_max(t.total, t.jackknife);
  } else if (!resampled_deviations.empty()) {
    for (const auto& d : resampled_deviations) t.resampled += d * d.transpose();
    t.resampled /= static_cast<double>(resampled_deviations.size());
    t.resampled_used = true;
    t.total = covariance_max(t.total, t.sandwich + t.resampled);
  }
  return t;
}

}  // namespace detail

}  // namespace rgbdt::extrinsics
