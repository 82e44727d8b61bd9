#include "rgbdt/extrinsics/initial_guess.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::extrinsics {

namespace {

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

struct Correspondence {
  Eigen::Vector3d center_lidar, normal_lidar;
  cv::RotatedRect ellipse;
  double radius_m;
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
  // Undistort the ellipse by sampling it and refitting in normalised coordinates (scaled by
  // fx so that fitEllipse works on pixel-like numbers).
  const double scale = camera.intrinsics().fx;
  const double a = 0.5 * ellipse_px.size.width, b = 0.5 * ellipse_px.size.height;
  const double phi = ellipse_px.angle * M_PI / 180.0;
  std::vector<cv::Point2f> samples;
  for (int i = 0; i < 72; ++i) {
    const double t = 2.0 * M_PI * i / 72.0;
    const Eigen::Vector2d px(ellipse_px.center.x + a * std::cos(t) * std::cos(phi) - b * std::sin(t) * std::sin(phi),
                             ellipse_px.center.y + a * std::cos(t) * std::sin(phi) + b * std::sin(t) * std::cos(phi));
    const Eigen::Vector3d ray = camera.unproject(px);
    samples.emplace_back(static_cast<float>(ray.x() * scale), static_cast<float>(ray.y() * scale));
  }
  const cv::RotatedRect e = cv::fitEllipse(samples);
  const double ea = 0.5 * e.size.width / scale, eb = 0.5 * e.size.height / scale;
  const double ephi = e.angle * M_PI / 180.0;
  const Eigen::Vector2d c(e.center.x / scale, e.center.y / scale);
  Eigen::Vector2d axis_major(std::cos(ephi), std::sin(ephi));
  Eigen::Vector2d axis_minor(-std::sin(ephi), std::cos(ephi));
  double major = ea, minor = eb;
  if (eb > ea) {
    std::swap(axis_major, axis_minor);
    std::swap(major, minor);
  }
  auto ray = [](const Eigen::Vector2d& xy) { return Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized(); };
  const Eigen::Vector3d ray_center = ray(c);
  const Eigen::Vector3d m1 = ray(c - major * axis_major), m2 = ray(c + major * axis_major);
  const Eigen::Vector3d n1 = ray(c - minor * axis_minor), n2 = ray(c + minor * axis_minor);
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

Eigen::Isometry3d align_rigid(const std::vector<Eigen::Vector3d>& points_a,
                              const std::vector<Eigen::Vector3d>& points_b,
                              const std::vector<Eigen::Vector3d>& directions_a,
                              const std::vector<Eigen::Vector3d>& directions_b,
                              double direction_weight_m2) {
  if (points_a.size() != points_b.size() || directions_a.size() != directions_b.size() ||
      points_a.empty()) {
    throw std::invalid_argument("align_rigid: expected matching, non-empty point lists (got " +
                                std::to_string(points_a.size()) + " and " +
                                std::to_string(points_b.size()) + " points)");
  }
  Eigen::Vector3d mean_a = Eigen::Vector3d::Zero(), mean_b = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < points_a.size(); ++i) {
    mean_a += points_a[i];
    mean_b += points_b[i];
  }
  mean_a /= points_a.size();
  mean_b /= points_b.size();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < points_a.size(); ++i)
    H += (points_a[i] - mean_a) * (points_b[i] - mean_b).transpose();
  for (size_t i = 0; i < directions_a.size(); ++i)
    H += direction_weight_m2 * directions_a[i] * directions_b[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  return core::make_transform(R, mean_b - R * mean_a);
}

InitialGuessResult closed_form_initial_guess(const std::vector<TargetView>& views,
                                             const core::PinholeCamera& camera) {
  InitialGuessResult out;
  std::vector<Correspondence> cs;
  for (const auto& v : views) {
    const size_t n = std::min({v.lidar_centers.size(), v.lidar_normals.size(), v.image_ellipses.size()});
    for (size_t k = 0; k < n; ++k) {
      if (v.image_ellipses[k].size.width > 1.0f && v.image_ellipses[k].size.height > 1.0f &&
          v.radius_m > 0.0 && v.lidar_centers[k].allFinite() && v.lidar_normals[k].allFinite())
        cs.push_back({v.lidar_centers[k], v.lidar_normals[k].normalized(), v.image_ellipses[k], v.radius_m});
    }
  }
  out.num_correspondences = static_cast<int>(cs.size());
  if (cs.size() < 2) {
    out.message = "needs at least 2 holes with a LIDAR centre, normal and image ellipse (got " +
                  std::to_string(cs.size()) + "); a single circle leaves the rotation about "
                  "its normal unobservable";
    return out;
  }

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
  std::vector<CircleInCamera> circles;
  for (const auto& c : cs) circles.push_back(circle_from_ellipse(c.ellipse, c.radius_m, camera));
  std::vector<Eigen::Vector3d> a, b, na, nb;
  for (size_t i = 0; i < cs.size(); ++i) {
    a.push_back(cs[i].center_lidar);
    b.push_back(circles[i].center);
    na.push_back(cs[i].normal_lidar);
  }
  // Choose the normal of each ellipse: enumerate the 2^n choices for few holes, else pick
  // the one closest to a centres-only alignment.
  auto alignment_cost = [&](const Eigen::Isometry3d& T, const std::vector<Eigen::Vector3d>& nbs) {
    double cost = 0.0;
    for (size_t i = 0; i < a.size(); ++i) cost += (T * a[i] - b[i]).squaredNorm();
    for (size_t i = 0; i < na.size(); ++i) cost += (T.linear() * na[i] - nbs[i]).squaredNorm();
    return cost;
  };
  if (cs.size() <= 10) {
    double best = std::numeric_limits<double>::infinity();
    Eigen::Isometry3d best_T = Eigen::Isometry3d::Identity();
    for (unsigned mask = 0; mask < (1u << cs.size()); ++mask) {
      nb.clear();
      for (size_t i = 0; i < cs.size(); ++i) nb.push_back(circles[i].normals[(mask >> i) & 1u]);
      const Eigen::Isometry3d T = align_rigid(a, b, na, nb);
      const double cost = alignment_cost(T, nb);
      if (cost < best) {
        best = cost;
        best_T = T;
      }
    }
    candidates.emplace_back(best_T, "ellipse poses + Kabsch on " + std::to_string(cs.size()) + " holes");
  } else {
    const Eigen::Isometry3d T0 = align_rigid(a, b);
    nb.clear();
    for (size_t i = 0; i < cs.size(); ++i) {
      const Eigen::Vector3d n = T0.linear() * na[i];
      nb.push_back((n - circles[i].normals[0]).norm() < (n - circles[i].normals[1]).norm()
                       ? circles[i].normals[0] : circles[i].normals[1]);
    }
    candidates.emplace_back(align_rigid(a, b, na, nb),
                            "ellipse poses + Kabsch on " + std::to_string(cs.size()) + " holes");
  }

  double best_rms = std::numeric_limits<double>::infinity();
  for (const auto& [T, how] : candidates) {
    const double rms = center_reprojection_rms(cs, camera, T);
    if (rms < best_rms) {
      best_rms = rms;
      out.T_camera_lidar = T;
      out.message = how;
    }
  }
  if (!std::isfinite(best_rms)) {
    out.message = "every candidate puts a hole centre behind the camera";
    return out;
  }
  double sum2 = 0.0;
  for (size_t i = 0; i < cs.size(); ++i) sum2 += (out.T_camera_lidar * a[i] - b[i]).squaredNorm();
  out.rms_center_m = std::sqrt(sum2 / cs.size());
  std::ostringstream os;
  os.precision(3);
  os << out.message << ", centre reprojection RMS " << best_rms << " px";
  out.message = os.str();
  out.ok = true;
  return out;
}

}  // namespace rgbdt::extrinsics
