#include "rgbdt/extrinsics/report.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace rgbdt::extrinsics {

cv::Mat to_display_bgr(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("to_display_bgr: empty image");
  cv::Mat grey_or_colour;
  if (image.depth() == CV_16U) {
    cv::Mat single = image;
    if (image.channels() != 1) cv::cvtColor(image, single, cv::COLOR_BGR2GRAY);
    std::vector<uint16_t> values(single.begin<uint16_t>(), single.end<uint16_t>());
    const size_t lo_i = values.size() / 100, hi_i = values.size() - 1 - values.size() / 100;
    std::nth_element(values.begin(), values.begin() + lo_i, values.end());
    const double lo = values[lo_i];
    std::nth_element(values.begin(), values.begin() + hi_i, values.end());
    const double hi = std::max(lo + 1.0, double(values[hi_i]));
    single.convertTo(grey_or_colour, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
  } else if (image.depth() == CV_8U) {
    grey_or_colour = image;
  } else {
    throw std::invalid_argument("to_display_bgr: image depth " + std::to_string(image.depth()) +
                                " is not 8U or 16U");
  }
  cv::Mat bgr;
  switch (grey_or_colour.channels()) {
    case 1: cv::cvtColor(grey_or_colour, bgr, cv::COLOR_GRAY2BGR); break;
    case 3: bgr = grey_or_colour.clone(); break;
    case 4: cv::cvtColor(grey_or_colour, bgr, cv::COLOR_BGRA2BGR); break;
    default:
      throw std::invalid_argument("to_display_bgr: " + std::to_string(grey_or_colour.channels()) +
                                  " channels (expected 1, 3 or 4)");
  }
  return bgr;
}

cv::Mat draw_overlay(const cv::Mat& image, const TargetView& view, const core::PinholeCamera& camera,
                     const Eigen::Isometry3d& T_camera_lidar_before,
                     const Eigen::Isometry3d& T_camera_lidar_after, const std::string& rejected) {
  cv::Mat out = to_display_bgr(image);
  for (const auto& p : view.image_edge_points_px)
    cv::circle(out, cv::Point(cvRound(p.x()), cvRound(p.y())), 1, cv::Scalar(255, 80, 0), -1);
  auto draw = [&](const Eigen::Isometry3d& T, const cv::Scalar& colour) {
    for (const auto& p : view.lidar_circle_points) {
      Eigen::Vector2d px;
      if (camera.project(T * p, &px) && camera.in_image(px))
        cv::circle(out, cv::Point(cvRound(px.x()), cvRound(px.y())), 1, colour, -1);
    }
  };
  draw(T_camera_lidar_before, cv::Scalar(0, 0, 255));
  draw(T_camera_lidar_after, cv::Scalar(0, 220, 0));
  cv::putText(out, view.name + "  blue: image edges  red: LIDAR before  green: after",
              cv::Point(10, 25), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 255, 255), 2);
  if (!rejected.empty()) {
    const int h = std::min(out.rows, 40);
    cv::rectangle(out, cv::Rect(0, out.rows - h, out.cols, h), cv::Scalar(0, 0, 200), cv::FILLED);
    cv::putText(out, "REJECTED: " + rejected, cv::Point(8, out.rows - h / 2 + 7), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(255, 255, 255), 2);
  }
  return out;
}

PoseError pose_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  return {core::rotation_error_rad(estimate, truth) * 180.0 / M_PI,
          core::translation_error_m(estimate, truth) * 100.0};
}

std::string format_alignment_report(const std::string& camera_name, const EdgeAlignmentResult& r,
                                    const std::optional<Eigen::Isometry3d>& truth) {
  std::ostringstream os;
  os << std::fixed;
  const core::Vector6d v = core::to_vector6(r.T_camera_lidar);
  const Eigen::Vector3d rpy = core::rotation_to_rpy(r.T_camera_lidar.linear()) * 180.0 / M_PI;
  os << "## " << camera_name << "\n\n";
  os << "T_" << camera_name << "_lidar (maps LIDAR points into the " << camera_name << " frame):\n\n";
  os << "| | value | 1 sigma |\n|---|---|---|\n";
  const char* names[6] = {"rx [rad]", "ry [rad]", "rz [rad]", "tx [m]", "ty [m]", "tz [m]"};
  for (int i = 0; i < 6; ++i) {
    os << "| " << names[i] << " | " << std::setprecision(6) << v[i] << " | ";
    if (r.covariance_valid) os << std::setprecision(6) << std::sqrt(std::max(0.0, r.covariance(i, i)));
    else os << "n/a";
    os << " |\n";
  }
  os << "\nroll pitch yaw [deg]: " << std::setprecision(4) << rpy.x() << " " << rpy.y() << " "
     << rpy.z() << "\n\n";
  os << "- converged: " << (r.converged ? "yes" : "no") << ", " << r.iterations
     << " iterations, " << std::setprecision(3) << r.solve_time_s << " s\n";
  os << "- RMS point-to-edge distance: " << std::setprecision(3) << r.rms_px << " px\n";
  os << "- start: " << (r.initial_from_closed_form ? "closed-form guess" : "given guess") << "\n";
  os << "- solver: " << r.message << "\n";
  if (truth) {
    const PoseError e = pose_error(r.T_camera_lidar, *truth);
    const PoseError e0 = pose_error(r.T_camera_lidar_initial, *truth);
    os << "- **error vs ground truth: " << std::setprecision(4) << e.rotation_deg << " deg, "
       << e.translation_cm << " cm** (start: " << e0.rotation_deg << " deg, " << e0.translation_cm
       << " cm)\n";
  }
  if (r.covariance_valid) {
    const CovarianceTerms& t = r.covariance_terms;
    os << "\nCovariance (rx ry rz tx ty tz; rad^2, m^2): image edges (clustered per hole) + the LIDAR "
          "circles' errors ("
       << t.holes_with_sigma << " of " << t.num_holes << " holes with a sigma from their detection)"
       << (t.jackknife_used ? ", at least the leave-one-view-out scatter" : "")
       << (t.resampled_used ? ", at least the spread of re-solves on circles moved by their errors (fewer than 3 views)"
                            : "")
       << ":\n\n```\n";
    os << std::scientific << std::setprecision(3);
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) os << (j ? " " : "") << std::setw(10) << r.covariance(i, j);
      os << "\n";
    }
    os << "```\n" << std::fixed;
  }
  os << "\n| view | points | in image | RMS [px] | median [px] | used | reason |\n"
        "|---|---|---|---|---|---|---|\n";
  for (const auto& vr : r.views) {
    os << "| " << vr.name << " | " << vr.num_points << " | " << vr.num_in_image << " | "
       << std::setprecision(3) << vr.rms_px << " | " << vr.median_px << " | "
       << (vr.used ? "yes" : "**no**") << " | " << vr.reason << " |\n";
  }
  os << "\n";
  return os.str();
}

CameraToCamera camera_to_camera(const Eigen::Isometry3d& T_a_lidar, const core::Matrix6d& cov_a,
                                const Eigen::Isometry3d& T_b_lidar, const core::Matrix6d& cov_b) {
  CameraToCamera out;
  const core::Vector6d xa = core::to_vector6(T_a_lidar), xb = core::to_vector6(T_b_lidar);
  auto f = [](const core::Vector6d& a, const core::Vector6d& b) {
    return core::to_vector6(core::from_vector6(b) * core::from_vector6(a).inverse());
  };
  out.T_b_a = T_b_lidar * T_a_lidar.inverse();
  // First-order propagation with central differences (the map is smooth away from a
  // rotation of pi, far from any camera pair).
  core::Matrix6d Ja, Jb;
  const double h = 1e-6;
  for (int i = 0; i < 6; ++i) {
    core::Vector6d d = core::Vector6d::Zero();
    d[i] = h;
    Ja.col(i) = (f(xa + d, xb) - f(xa - d, xb)) / (2 * h);
    Jb.col(i) = (f(xa, xb + d) - f(xa, xb - d)) / (2 * h);
  }
  out.covariance = Ja * cov_a * Ja.transpose() + Jb * cov_b * Jb.transpose();
  return out;
}

}  // namespace rgbdt::extrinsics
