#pragma once
// Synthetic circle-target views for the tests and the benchmark: the protocol of paper
// Sec. 4.2 (circles at different poses, a camera with known intrinsics and extrinsics, the
// circles projected to make the image edges).
#include <array>
#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics::testing {

inline core::CameraIntrinsics table1_intrinsics(bool distorted = false) {
  core::CameraIntrinsics in;
  in.camera_name = "rgb";
  in.width = 1288;
  in.height = 964;
  in.fx = 1335.0;
  in.fy = 1335.0;
  in.cx = 644.0;
  in.cy = 482.0;
  in.model = core::DistortionModel::kPlumbBob;
  in.distortion = distorted ? std::vector<double>{-0.12, 0.08, 0.0005, -0.0003, 0.0}
                            : std::vector<double>{0, 0, 0, 0, 0};
  return in;
}

/// LIDAR x forward, y left, z up; camera x right, y down, z forward; the camera sits a
/// little to the side of and above the LIDAR and is slightly misaligned.
inline Eigen::Isometry3d true_T_camera_lidar() {
  Eigen::Matrix3d R_base;
  R_base << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const Eigen::Matrix3d R = core::rotation_from_rpy(0.02, -0.035, 0.01) * R_base;
  return core::make_transform(R, Eigen::Vector3d(0.06, -0.11, 0.04));
}

struct Placement {
  Eigen::Vector3d center_lidar;  ///< [m]
  double yaw_deg, pitch_deg;     ///< board tilt away from facing the LIDAR
};

/// Eight placements spread over the field of view at 3-6 m, tilted in different ways.
inline std::vector<Placement> table1_placements() {
  return {{{3.0, 0.6, 0.3}, 25, 10},   {{3.5, -0.7, -0.2}, -30, 5},
          {{4.0, 0.0, 0.6}, 10, -30},  {{4.5, 1.0, -0.4}, -15, 25},
          {{5.0, -1.2, 0.4}, 35, -10}, {{5.5, 0.3, -0.6}, -5, 35},
          {{6.0, 1.3, 0.1}, 20, 20},   {{3.2, -0.1, -0.1}, -35, -25}};
}

/// The board's unit normal (towards the LIDAR, then tilted by the placement) and two in-plane
/// axes: e1 horizontal, e2 = normal x e1.
inline std::array<Eigen::Vector3d, 3> board_axes(const Placement& pl) {
  const Eigen::Vector3d facing = -pl.center_lidar.normalized();
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(pl.yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                Eigen::AngleAxisd(pl.pitch_deg * M_PI / 180, Eigen::Vector3d::UnitY()))
                                   .toRotationMatrix();
  const Eigen::Vector3d normal = (tilt * facing).normalized();
  const Eigen::Vector3d e1 = normal.cross(Eigen::Vector3d::UnitZ()).normalized();
  return {normal, e1, normal.cross(e1)};
}

/// One view per placement: 360 circle points (1 degree steps) and, as image edges, their
/// projections with the true extrinsics (noiseless, as in the paper's test).
inline std::vector<TargetView> make_views(const core::PinholeCamera& camera,
                                          const Eigen::Isometry3d& T_camera_lidar,
                                          const std::vector<Placement>& placements,
                                          double radius_m = 0.3, int points_per_circle = 360) {
  std::vector<TargetView> views;
  for (size_t i = 0; i < placements.size(); ++i) {
    const Placement& pl = placements[i];
    const auto [normal, e1, e2] = board_axes(pl);
    TargetView v;
    v.name = "view " + std::to_string(i);
    v.radius_m = radius_m;
    v.image_width = camera.width();
    v.image_height = camera.height();
    std::vector<cv::Point2f> projected;
    for (int k = 0; k < points_per_circle; ++k) {
      const double t = 2.0 * M_PI * k / points_per_circle;
      const Eigen::Vector3d p = pl.center_lidar + radius_m * (std::cos(t) * e1 + std::sin(t) * e2);
      v.lidar_circle_points.push_back(p);
      Eigen::Vector2d px;
      if (camera.project(T_camera_lidar * p, &px)) {
        v.image_edge_points_px.push_back(px);
        projected.emplace_back(static_cast<float>(px.x()), static_cast<float>(px.y()));
      }
    }
    v.lidar_centers.push_back(pl.center_lidar);
    v.lidar_normals.push_back(normal);
    v.image_ellipses.push_back(cv::fitEllipse(projected));
    views.push_back(std::move(v));
  }
  return views;
}

/// Initial estimate offset as in Table 1: the camera's pose in the LIDAR frame is rotated
/// by (roll, pitch, yaw) [deg] about the LIDAR axes and shifted by (tx, ty, tz) [m].
inline Eigen::Isometry3d offset_guess(const Eigen::Isometry3d& T_camera_lidar, double roll_deg,
                                      double pitch_deg, double yaw_deg, double tx, double ty,
                                      double tz) {
  const Eigen::Isometry3d T_lidar_camera = T_camera_lidar.inverse();
  const Eigen::Matrix3d dR = core::rotation_from_rpy(roll_deg * M_PI / 180, pitch_deg * M_PI / 180,
                                                     yaw_deg * M_PI / 180);
  const Eigen::Isometry3d guess = core::make_transform(
      dR * T_lidar_camera.linear(), T_lidar_camera.translation() + Eigen::Vector3d(tx, ty, tz));
  return guess.inverse();
}

/// Per-axis errors like Table 1: |roll pitch yaw| [deg] of the rotation error of the camera
/// pose in the LIDAR frame, and |tx ty tz| [cm] of its position error.
inline Eigen::Matrix<double, 6, 1> table1_errors(const Eigen::Isometry3d& estimate,
                                                 const Eigen::Isometry3d& truth) {
  const Eigen::Isometry3d e = estimate.inverse(), t = truth.inverse();
  const Eigen::Vector3d rpy = core::rotation_to_rpy(e.linear() * t.linear().transpose());
  Eigen::Matrix<double, 6, 1> out;
  out.head<3>() = rpy.cwiseAbs() * 180.0 / M_PI;
  out.tail<3>() = (e.translation() - t.translation()).cwiseAbs() * 100.0;
  return out;
}

}  // namespace rgbdt::extrinsics::testing
