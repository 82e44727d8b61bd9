#pragma once
/// \file
/// What the calibration app shows: overlays of the LIDAR circle points on the images,
/// a Markdown report of an edge alignment, and the camera-to-camera transform derived from
/// two camera-LIDAR calibrations.
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics {

/// 8-bit BGR copy of any 8U/16U, 1/3/4-channel image (16-bit thermal is stretched between
/// its 1st and 99th percentiles). Throws std::invalid_argument for other types.
cv::Mat to_display_bgr(const cv::Mat& image);

/// The image with the view's image edge points (blue), the LIDAR circle points projected
/// with T_before (red) and with T_after (green). A non-empty `rejected` is written on a red
/// banner across the bottom ("REJECTED: <rejected>"): the view or the whole estimate failed.
cv::Mat draw_overlay(const cv::Mat& image, const TargetView& view, const core::PinholeCamera& camera,
                     const Eigen::Isometry3d& T_camera_lidar_before,
                     const Eigen::Isometry3d& T_camera_lidar_after, const std::string& rejected = {});

/// Errors of an estimate against a reference: rotation angle [deg], translation [cm].
struct PoseError {
  double rotation_deg = 0.0;
  double translation_cm = 0.0;
};
PoseError pose_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth);

/// Markdown section for one camera: estimate, 1-sigma from the covariance, per-view
/// residuals, rejected views and, when given, errors against the truth.
std::string format_alignment_report(const std::string& camera_name, const EdgeAlignmentResult& result,
                                    const std::optional<Eigen::Isometry3d>& T_camera_lidar_truth = {});

/// T_b_a = T_b_lidar * T_a_lidar^-1 and its first-order covariance ([rx ry rz tx ty tz] of
/// T_b_a), treating the two calibrations as independent.
struct CameraToCamera {
  Eigen::Isometry3d T_b_a = Eigen::Isometry3d::Identity();
  core::Matrix6d covariance = core::Matrix6d::Zero();
};
CameraToCamera camera_to_camera(const Eigen::Isometry3d& T_a_lidar, const core::Matrix6d& cov_a,
                                const Eigen::Isometry3d& T_b_lidar, const core::Matrix6d& cov_b);

}  // namespace rgbdt::extrinsics
