#include "rgbdt/extrinsics/initial_guess.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <array>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/transform.hpp"
#include "rgbdt/extrinsics/hole_pairing.hpp"

namespace rgbdt::extrinsics {

namespace {

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

struct Correspondence {
  Eigen::Vector3d center_lidar, normal_lidar;
  cv::RotatedRect ellipse;
  double radius_m;
  CircleInCamera circle;  ///< circle_from_ellipse(ellipse, radius_m)
};

/// RMS [px] of the LIDAR hole centres projected with T against the ellipse centres; +inf
/// when a centre falls behind the camera.
double center_reprojection_rms(const std::vector<Correspondence>& cs,
                               const core::PinholeCamera& camera, const Eigen::Isometry3d& T) {
  double sum2 = 0.0;
  for (const auto& c : cs) {
    Eigen::Vector2d px;
    if (!camera.project(T * c.center_lidar, &px)) return std::numeric_limits<double>::infinity();
    sum2 += (px - Eigen::Vector2d(c.ellipse.center.x, c.ellipse.center.y)).squaredNorm();
  }
  return std::sqrt(sum2 / std::max<size_t>(1, cs.size()));
}

/// Two start poses at least this far apart in rotation whose fits differ by less than
/// kAmbiguousRmsFactor x + kAmbiguousRmsPx are reported as ambiguous.
constexpr double kAmbiguousRotationRad = 20.0 * M_PI / 180.0;
constexpr double kAmbiguousRmsFactor = 1.5;
constexpr double kAmbiguousRmsPx = 2.0;

/// Points sampled on an image ellipse to undistort it. The fit of a smooth closed curve
/// sampled evenly in its parameter converges fast: on the simulator's cameras 16 samples
/// give the circle centres of 144 to ~1e-12 px (12 samples: ~1e-9 px).
constexpr int kEllipseSamples = 16;
using EllipseSamples = std::array<Eigen::Vector2d, kEllipseSamples>;

/// An ellipse in normalised image coordinates.
struct NormalisedEllipse {
  Eigen::Vector2d center, major_axis, minor_axis;  // axes: unit directions
  double major = 0.0, minor = 0.0;                 // semi-axes
};

/// The ellipse's points evenly spaced in its parameter, undistorted to normalised coordinates.
EllipseSamples undistorted_samples(const cv::RotatedRect& ellipse_px, const core::PinholeCamera& camera) {
  const double a = 0.5 * ellipse_px.size.width, b = 0.5 * ellipse_px.size.height;
  const double phi = ellipse_px.angle * M_PI / 180.0;
  const double cos_phi = std::cos(phi), sin_phi = std::sin(phi);
  EllipseSamples samples;
  for (int i = 0; i < kEllipseSamples; ++i) {
    const double t = 2.0 * M_PI * i / kEllipseSamples;
    const double u = a * std::cos(t), v = b * std::sin(t);
    const Eigen::Vector2d px(ellipse_px.center.x + u * cos_phi - v * sin_phi,
                             ellipse_px.center.y + u * sin_phi + v * cos_phi);
    samples[i] = camera.unproject(px).head<2>();
  }
  return samples;
}

/// Least-squares conic A x^2 + B xy + C y^2 + D x + E y = 1 through the samples (centred on
/// their mean and scaled to unit spread), solved from its 5x5 normal equations; nullopt
/// when the conic is not a real ellipse.
std::optional<NormalisedEllipse> fit_conic(const EllipseSamples& samples) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& q : samples) mean += q;
  mean /= kEllipseSamples;
  double spread2 = 0.0;
  for (const auto& q : samples) spread2 += (q - mean).squaredNorm();
  const double scale = std::sqrt(spread2 / kEllipseSamples);
  if (!(scale > 0.0)) return std::nullopt;
  Eigen::Matrix<double, 5, 5> normal = Eigen::Matrix<double, 5, 5>::Zero();
  Eigen::Matrix<double, 5, 1> rhs = Eigen::Matrix<double, 5, 1>::Zero();
  for (const auto& q : samples) {
    const Eigen::Vector2d p = (q - mean) / scale;
    const Eigen::Matrix<double, 5, 1> row(p.x() * p.x(), p.x() * p.y(), p.y() * p.y(), p.x(), p.y());
    normal.selfadjointView<Eigen::Lower>().rankUpdate(row);
    rhs += row;
  }
  const Eigen::Matrix<double, 5, 1> k = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
  // (p - c)' S (p - c) = 1 + c' S c, with S the quadratic part and c the centre.
  Eigen::Matrix2d S;
  S << k(0), 0.5 * k(1), 0.5 * k(1), k(2);
  const Eigen::Vector2d c = S.inverse() * Eigen::Vector2d(-0.5 * k(3), -0.5 * k(4));
  const double level = 1.0 + c.dot(S * c);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig;
  eig.computeDirect(S / level);
  const Eigen::Vector2d lambda = eig.eigenvalues();  // ascending: the major axis first
  if (!c.allFinite() || !(lambda(0) > 0.0) || !std::isfinite(lambda(1))) return std::nullopt;
  NormalisedEllipse e;
  e.center = mean + scale * c;
  // The major axis points to -x as cv::RotatedRect's does (angle in [0, 180] deg): its
  // sign orders the two normals of circle_from_normalised_ellipse.
  e.major_axis = eig.eigenvectors().col(0);
  if (e.major_axis.x() > 0.0) e.major_axis = -e.major_axis;
  e.minor_axis = Eigen::Vector2d(e.major_axis.y(), -e.major_axis.x());
  e.major = scale / std::sqrt(lambda(0));
  e.minor = scale / std::sqrt(lambda(1));
  return e;
}

/// cv::fitEllipse of the samples (scaled by fx to pixel-like numbers), where fit_conic
/// finds no ellipse.
NormalisedEllipse fit_ellipse_cv(const EllipseSamples& samples, double fx) {
  std::vector<cv::Point2f> points;
  for (const auto& q : samples) points.emplace_back(static_cast<float>(q.x() * fx), static_cast<float>(q.y() * fx));
  const cv::RotatedRect r = cv::fitEllipse(points);
  const double angle = r.angle * M_PI / 180.0;
  NormalisedEllipse e;
  e.center = Eigen::Vector2d(r.center.x, r.center.y) / fx;
  e.major_axis = Eigen::Vector2d(std::cos(angle), std::sin(angle));
  e.minor_axis = Eigen::Vector2d(-std::sin(angle), std::cos(angle));
  e.major = 0.5 * r.size.width / fx;
  e.minor = 0.5 * r.size.height / fx;
  if (e.minor > e.major) {
    std::swap(e.major_axis, e.minor_axis);
    std::swap(e.major, e.minor);
  }
  return e;
}

/// The circle of radius_m whose image is the (undistorted) ellipse e.
CircleInCamera circle_from_normalised_ellipse(const NormalisedEllipse& e, double radius_m) {
  auto ray = [](const Eigen::Vector2d& xy) { return Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized(); };
  const Eigen::Vector3d ray_center = ray(e.center);
  const Eigen::Vector3d m1 = ray(e.center - e.major * e.major_axis), m2 = ray(e.center + e.major * e.major_axis);
  const Eigen::Vector3d n1 = ray(e.center - e.minor * e.minor_axis), n2 = ray(e.center + e.minor * e.minor_axis);
  const double alpha = 0.5 * angle_between(m1, m2);  // angular radius along the major axis
  const double beta = 0.5 * angle_between(n1, n2);
  // The diameter seen along the major axis is (nearly) parallel to the image plane.
  const double distance_m = radius_m / std::tan(alpha);
  const double cos_tilt = std::clamp(std::tan(beta) / std::tan(alpha), 0.0, 1.0);
  const double tilt = std::acos(cos_tilt);
  Eigen::Vector3d tilt_axis = m2 - m1;
  tilt_axis -= tilt_axis.dot(ray_center) * ray_center;
  tilt_axis.normalize();
  CircleInCamera out;
  out.center = distance_m * ray_center;
  const Eigen::Vector3d facing = -ray_center;
  out.normals[0] = Eigen::AngleAxisd(tilt, tilt_axis) * facing;
  out.normals[1] = Eigen::AngleAxisd(-tilt, tilt_axis) * facing;
  return out;
}

}  // namespace

CircleInCamera circle_from_ellipse(const cv::RotatedRect& ellipse_px, double radius_m,
                                   const core::PinholeCamera& camera) {
  if (!(radius_m > 0.0)) {
    throw std::invalid_argument("circle_from_ellipse: radius_m = " + std::to_string(radius_m) +
                                ", expected > 0");
  }
  if (!(ellipse_px.size.width > 1.0f && ellipse_px.size.height > 1.0f)) {
    throw std::invalid_argument("circle_from_ellipse: degenerate ellipse (axes " +
                                std::to_string(ellipse_px.size.width) + " x " +
                                std::to_string(ellipse_px.size.height) + " px)");
  }
  // Undistort the ellipse by sampling it and refitting an ellipse in normalised coordinates.
  const EllipseSamples samples = undistorted_samples(ellipse_px, camera);
  const std::optional<NormalisedEllipse> fit = fit_conic(samples);
  return circle_from_normalised_ellipse(fit ? *fit : fit_ellipse_cv(samples, camera.intrinsics().fx), radius_m);
}

namespace {

/// The point part of align_rigid, shared by alignments that differ only in their directions.
struct PointMoments {
  Eigen::Vector3d mean_a, mean_b;
  Eigen::Matrix3d H;  ///< cross-covariance of the centred points
};

PointMoments point_moments(const std::vector<Eigen::Vector3d>& points_a,
                           const std::vector<Eigen::Vector3d>& points_b) {
  if (points_a.size() != points_b.size() || points_a.empty()) {
    throw std::invalid_argument("align_rigid: expected matching, non-empty point lists (got " +
                                std::to_string(points_a.size()) + " and " +
                                std::to_string(points_b.size()) + " points)");
  }
  PointMoments m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero()};
  for (size_t i = 0; i < points_a.size(); ++i) {
    m.mean_a += points_a[i];
    m.mean_b += points_b[i];
  }
  m.mean_a /= points_a.size();
  m.mean_b /= points_b.size();
  for (size_t i = 0; i < points_a.size(); ++i)
    m.H += (points_a[i] - m.mean_a) * (points_b[i] - m.mean_b).transpose();
  return m;
}

/// align_rigid from the points' moments and the direction pairs.
Eigen::Isometry3d align_moments(const PointMoments& m, const std::vector<Eigen::Vector3d>& directions_a,
                                const std::vector<Eigen::Vector3d>& directions_b, double direction_weight_m2) {
  Eigen::Matrix3d H = m.H;
  for (size_t i = 0; i < directions_a.size(); ++i)
    H += direction_weight_m2 * directions_a[i] * directions_b[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  return core::make_transform(R, m.mean_b - R * m.mean_a);
}

}  // namespace

Eigen::Isometry3d align_rigid(const std::vector<Eigen::Vector3d>& points_a,
                              const std::vector<Eigen::Vector3d>& points_b,
                              const std::vector<Eigen::Vector3d>& directions_a,
                              const std::vector<Eigen::Vector3d>& directions_b,
                              double direction_weight_m2) {
  if (directions_a.size() != directions_b.size()) {
    throw std::invalid_argument("align_rigid: expected matching direction lists (got " +
                                std::to_string(directions_a.size()) + " and " +
                                std::to_string(directions_b.size()) + " directions)");
  }
  return align_moments(point_moments(points_a, points_b), directions_a, directions_b, direction_weight_m2);
}

namespace {

/// Up to this many holes, solve_pairing tries every choice of the ellipses' normals.
constexpr std::size_t kExhaustiveNormalChoices = 6;

/// One view's holes as the two detectors list them (each in its own order).
struct ViewHoles {
  std::vector<Eigen::Vector3d> centers, normals;  // LIDAR frame
  std::vector<cv::RotatedRect> ellipses;          // image
  std::vector<CircleInCamera> circles;            // circle_from_ellipse of each ellipse
  double radius_m = 0.0;
};

/// Which ellipse each LIDAR hole of each view is paired with.
using Pairing = std::vector<std::vector<std::size_t>>;

std::vector<Correspondence> correspondences(const std::vector<ViewHoles>& views, const Pairing& pairing) {
  std::vector<Correspondence> cs;
  for (std::size_t v = 0; v < views.size(); ++v) {
    for (std::size_t k = 0; k < pairing[v].size(); ++k)
      cs.push_back({views[v].centers[k], views[v].normals[k], views[v].ellipses[pairing[v][k]], views[v].radius_m,
                    views[v].circles[pairing[v][k]]});
  }
  return cs;
}

/// The detectors' own order: hole k with ellipse k.
Pairing index_pairing(const std::vector<ViewHoles>& views) {
  Pairing p(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) {
    p[v].resize(std::min(views[v].centers.size(), views[v].ellipses.size()));
    std::iota(p[v].begin(), p[v].end(), std::size_t{0});
  }
  return p;
}

/// Each view's LIDAR holes projected with T and paired with the nearest ellipses; nullopt
/// when a centre falls behind the camera.
std::optional<Pairing> pairing_at(const std::vector<ViewHoles>& views, const core::PinholeCamera& camera,
                                  const Eigen::Isometry3d& T) {
  Pairing p(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (views[v].centers.size() > views[v].ellipses.size()) {  // as many as pair, in order
      p[v].resize(views[v].ellipses.size());
      std::iota(p[v].begin(), p[v].end(), std::size_t{0});
      continue;
    }
    std::vector<Eigen::Vector2d> px(views[v].centers.size());
    for (std::size_t k = 0; k < px.size(); ++k)
      if (!camera.project(T * views[v].centers[k], &px[k])) return std::nullopt;
    p[v] = pair_holes_by_position(px, views[v].ellipses);
  }
  return p;
}

/// T_camera_lidar candidates for one pairing: PnP on the hole centres and the ellipse poses
/// aligned with the LIDAR centres and normals.
std::vector<std::pair<Eigen::Isometry3d, std::string>> solve_pairing(const std::vector<Correspondence>& cs,
                                                                     const core::PinholeCamera& camera) {
  std::vector<std::pair<Eigen::Isometry3d, std::string>> candidates;
  // (A) PnP on the hole centres of all views (object points in the LIDAR frame).
  if (cs.size() >= 4) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const auto& c : cs) {
      object.emplace_back(c.center_lidar.x(), c.center_lidar.y(), c.center_lidar.z());
      const Eigen::Vector3d ray = camera.unproject({c.ellipse.center.x, c.ellipse.center.y});
      image.emplace_back(ray.x(), ray.y());
    }
    cv::Mat rvec, tvec;
    try {
      if (cv::solvePnP(object, image, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false,
                       cv::SOLVEPNP_SQPNP)) {
        const Eigen::Vector3d r(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
        const Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
        candidates.emplace_back(core::make_transform(core::rotation_from_vector(r), t),
                                "PnP on " + std::to_string(cs.size()) + " hole centres");
      }
    } catch (const cv::Exception&) {
      // Degenerate configurations (e.g. collinear centres): the ellipse poses below remain.
    }
  }

  // (B) Circle poses from the ellipses, aligned with the LIDAR centres and normals.
  std::vector<Eigen::Vector3d> a, b, na;
  for (std::size_t i = 0; i < cs.size(); ++i) {
    a.push_back(cs[i].center_lidar);
    b.push_back(cs[i].circle.center);
    na.push_back(cs[i].normal_lidar);
  }
  // Each ellipse has two circle normals. Few holes: every choice (2^n alignments). More: the
  // normals nearest to the LIDAR's under a rotation from the other evidence (the centres
  // alone, and PnP's when it ran), then single flips while one lowers the cost, so the
  // search stays a few alignments per hole rather than 2^n (1024 at 10 views of one hole).
  const auto alignment_cost = [&](const Eigen::Isometry3d& T, const std::vector<Eigen::Vector3d>& nbs) {
    double cost = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) cost += (T * a[i] - b[i]).squaredNorm();
    for (std::size_t i = 0; i < na.size(); ++i) cost += (T.linear() * na[i] - nbs[i]).squaredNorm();
    return cost;
  };
  // Every alignment below shares the centres; only the choice of normals changes.
  const PointMoments centers = point_moments(a, b);
  std::vector<Eigen::Vector3d> nb_of(cs.size());
  const auto align_with = [&](const std::vector<bool>& choice, double* cost) {
    for (std::size_t i = 0; i < cs.size(); ++i) nb_of[i] = cs[i].circle.normals[choice[i] ? 1 : 0];
    const Eigen::Isometry3d T = align_moments(centers, na, nb_of, kDirectionWeightM2);
    *cost = alignment_cost(T, nb_of);
    return T;
  };
  const std::string how = "ellipse poses + Kabsch on " + std::to_string(cs.size()) + " holes";
  double best = std::numeric_limits<double>::infinity();
  Eigen::Isometry3d best_T = Eigen::Isometry3d::Identity();
  const auto keep = [&](const Eigen::Isometry3d& T, double cost) {
    if (cost < best) {
      best = cost;
      best_T = T;
    }
  };
  std::vector<bool> choice(cs.size());
  if (cs.size() <= kExhaustiveNormalChoices) {
    for (unsigned mask = 0; mask < (1u << cs.size()); ++mask) {
      for (std::size_t i = 0; i < cs.size(); ++i) choice[i] = ((mask >> i) & 1u) != 0;
      double cost = 0.0;
      const Eigen::Isometry3d T = align_with(choice, &cost);
      keep(T, cost);
    }
  } else {
    std::vector<Eigen::Matrix3d> references{align_moments(centers, {}, {}, kDirectionWeightM2).linear()};
    if (!candidates.empty()) references.push_back(candidates.front().first.linear());
    for (const Eigen::Matrix3d& R : references) {
      for (std::size_t i = 0; i < cs.size(); ++i) {
        const Eigen::Vector3d n = R * na[i];
        choice[i] = (n - cs[i].circle.normals[1]).norm() < (n - cs[i].circle.normals[0]).norm();
      }
      double cost = 0.0;
      Eigen::Isometry3d T = align_with(choice, &cost);
      for (bool improved = true; improved;) {
        improved = false;
        for (std::size_t i = 0; i < cs.size(); ++i) {
          choice[i] = !choice[i];
          double flipped_cost = 0.0;
          const Eigen::Isometry3d flipped = align_with(choice, &flipped_cost);
          if (flipped_cost < cost) {
            cost = flipped_cost;
            T = flipped;
            improved = true;
          } else {
            choice[i] = !choice[i];
          }
        }
      }
      keep(T, cost);
    }
  }
  candidates.emplace_back(best_T, how);
  return candidates;
}

/// Start poses from one view of three or more holes: its LIDAR centres aligned with the
/// ellipses' circle centres under every pairing (up to 7 holes), the best few kept. A
/// symmetric layout fits several pairings equally; the views together tell them apart.
std::vector<Eigen::Isometry3d> view_pairing_starts(const ViewHoles& v) {
  const std::size_t n = v.centers.size();
  if (n < 3 || v.ellipses.size() < n || v.ellipses.size() > 7) return {};
  std::vector<Eigen::Vector3d> circle_centers;
  for (const auto& c : v.circles) circle_centers.push_back(c.center);
  std::vector<std::size_t> perm(v.ellipses.size());
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  std::vector<std::pair<double, Eigen::Isometry3d>> fits;
  std::vector<Eigen::Vector3d> b(n);
  do {
    for (std::size_t k = 0; k < n; ++k) b[k] = circle_centers[perm[k]];
    const Eigen::Isometry3d T = align_rigid(v.centers, b);
    double sum2 = 0.0;
    for (std::size_t k = 0; k < n; ++k) sum2 += (T * v.centers[k] - b[k]).squaredNorm();
    fits.emplace_back(sum2, T);
  } while (std::next_permutation(perm.begin(), perm.end()));
  std::sort(fits.begin(), fits.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<Eigen::Isometry3d> starts;
  for (std::size_t i = 0; i < std::min<std::size_t>(fits.size(), 4); ++i) starts.push_back(fits[i].second);
  return starts;
}

}  // namespace

InitialGuessResult closed_form_initial_guess(const std::vector<TargetView>& views,
                                             const core::PinholeCamera& camera) {
  InitialGuessResult out;
  // Each view's valid holes, in each detector's own order: the pairing is found below.
  std::vector<ViewHoles> holes;
  for (const auto& v : views) {
    if (!(v.radius_m > 0.0)) continue;
    ViewHoles h;
    h.radius_m = v.radius_m;
    for (std::size_t k = 0; k < std::min(v.lidar_centers.size(), v.lidar_normals.size()); ++k) {
      if (v.lidar_centers[k].allFinite() && v.lidar_normals[k].allFinite() && v.lidar_normals[k].norm() > 0.0) {
        h.centers.push_back(v.lidar_centers[k]);
        h.normals.push_back(v.lidar_normals[k].normalized());
      }
    }
    for (const auto& e : v.image_ellipses) {
      if (!(e.size.width > 1.0f && e.size.height > 1.0f)) continue;
      h.ellipses.push_back(e);
      h.circles.push_back(circle_from_ellipse(e, h.radius_m, camera));
    }
    if (!h.centers.empty() && !h.ellipses.empty()) holes.push_back(std::move(h));
  }
  const Pairing by_index = index_pairing(holes);
  out.num_correspondences = static_cast<int>(correspondences(holes, by_index).size());
  if (out.num_correspondences < 2) {
    out.message = "needs at least 2 holes with a LIDAR centre, normal and image ellipse (got " +
                  std::to_string(out.num_correspondences) + "); a single circle leaves the rotation about "
                  "its normal unobservable";
    return out;
  }

  // The LIDAR and image detectors each order a view's holes from their own viewpoint, so
  // the pairing is part of the unknown. Start poses: the detectors' order, and each view of
  // three or more holes aligned under its best-fitting pairings. From each start pose every
  // view is paired by position and solved again; the pose whose hole centres reproject best
  // under its own pairing wins.
  std::vector<Pairing> tried;
  struct Solution {
    Eigen::Isometry3d T;
    std::string how;
    double rms_px;
    Pairing pairing;
  };
  std::vector<Solution> solutions;  // the best of each distinct pairing
  const auto evaluate = [&](const Pairing& pairing) {
    if (std::find(tried.begin(), tried.end(), pairing) != tried.end()) return;
    tried.push_back(pairing);
    const std::vector<Correspondence> cs = correspondences(holes, pairing);
    Solution best{Eigen::Isometry3d::Identity(), "", std::numeric_limits<double>::infinity(), pairing};
    for (const auto& [T, how] : solve_pairing(cs, camera)) {
      const double rms = center_reprojection_rms(cs, camera, T);
      if (rms < best.rms_px) best = {T, how, rms, pairing};
    }
    if (std::isfinite(best.rms_px)) solutions.push_back(best);
  };
  evaluate(by_index);
  std::vector<Eigen::Isometry3d> starts;
  for (const auto& s : solutions) starts.push_back(s.T);
  for (const auto& h : holes)
    for (const auto& T : view_pairing_starts(h)) starts.push_back(T);
  for (const auto& T : starts) {
    if (const auto p = pairing_at(holes, camera, T)) evaluate(*p);
  }
  // A solution's own position pairing can differ from the one it was solved with; one more
  // round settles it.
  for (std::size_t i = 0, n = solutions.size(); i < n; ++i) {
    if (const auto p = pairing_at(holes, camera, solutions[i].T)) evaluate(*p);
  }
  if (solutions.empty()) {
    out.message = "every candidate puts a hole centre behind the camera";
    return out;
  }
  std::sort(solutions.begin(), solutions.end(),
            [](const Solution& x, const Solution& y) { return x.rms_px < y.rms_px; });
  // Poses far from the best that fit nearly as well: the board's hole layout is symmetric
  // and these views do not tell its orientations apart. Among them the one that mounts the
  // LIDAR the same way up as the camera is taken: the LIDAR's +z (up, REP 103) closest to
  // the camera's up (-y of its optical frame). The detectors' hole order is no help here: a
  // board rolled ~45 deg in the view makes "top-left" differ between them.
  const auto rivals = [&](const Solution& a, const Solution& b) {
    return core::rotation_error_rad(a.T, b.T) > kAmbiguousRotationRad &&
           std::max(a.rms_px, b.rms_px) < kAmbiguousRmsFactor * std::min(a.rms_px, b.rms_px) + kAmbiguousRmsPx;
  };
  const auto upright = [](const Solution& s) { return -(s.T.linear() * Eigen::Vector3d::UnitZ()).y(); };
  std::size_t chosen = 0;
  for (std::size_t i = 1; i < solutions.size(); ++i) {
    if (rivals(solutions[i], solutions[0]) && upright(solutions[i]) > upright(solutions[chosen])) chosen = i;
  }
  const Solution best = solutions[chosen];
  for (std::size_t i = 0; i < solutions.size(); ++i) {
    const Solution& s = solutions[i];
    if (i == chosen || !rivals(s, best)) continue;
    out.ambiguous = true;
    std::ostringstream os;
    os.precision(3);
    os << "a pose " << core::rotation_error_rad(s.T, best.T) * 180.0 / M_PI
       << " deg away pairs the holes otherwise and fits about as well (" << s.rms_px << " px against "
       << best.rms_px << " px): the board's hole layout is symmetric from these views";
    os << "; the pose taken assumes the LIDAR is mounted the same way up as the camera (its +z towards the "
          "image's top)";
    out.ambiguity = os.str();
    break;
  }
  out.T_camera_lidar = best.T;
  double sum2 = 0.0;
  const std::vector<Correspondence> cs = correspondences(holes, best.pairing);
  for (const auto& c : cs) sum2 += (best.T * c.center_lidar - c.circle.center).squaredNorm();
  out.rms_center_m = std::sqrt(sum2 / static_cast<double>(cs.size()));
  out.num_correspondences = static_cast<int>(cs.size());
  std::ostringstream os;
  os.precision(3);
  os << best.how << ", centre reprojection RMS " << best.rms_px << " px";
  if (solutions.size() > 1) os << " (best of " << solutions.size() << " hole pairings)";
  out.message = os.str();
  out.ok = true;
  return out;
}

}  // namespace rgbdt::extrinsics
