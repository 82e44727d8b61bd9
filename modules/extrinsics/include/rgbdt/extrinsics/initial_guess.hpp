#pragma once
/// \file
/// Closed-form T_camera_lidar from the views, so that no user guess is needed.
///
/// For each hole, the LIDAR fit gives its centre and normal (LIDAR frame). In the image,
/// the hole's ellipse and the known radius give the circle's centre in the camera frame
/// (distance from the angular size of the major axis, direction from the ellipse centre)
/// and its normal up to a two-fold ambiguity (tilt acos(minor/major) about the major
/// axis). With four or more holes in one view, PnP on the hole centres (cv::solvePnP with
/// the board layout recovered from the LIDAR centres) replaces the ellipse estimate. The
/// centres (and the disambiguated normals) of all views are then aligned rigidly
/// (Umeyama/Kabsch, no scale).
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/extrinsics/target_view.hpp"

namespace rgbdt::extrinsics {

struct CircleInCamera {
  Eigen::Vector3d center;      ///< [m], camera frame
  Eigen::Vector3d normals[2];  ///< the two candidate unit normals, pointing to the camera
};

/// Circle pose from its (distorted) image ellipse. Throws std::invalid_argument for a
/// degenerate ellipse or radius.
CircleInCamera circle_from_ellipse(const cv::RotatedRect& ellipse_px, double radius_m,
                                   const core::PinholeCamera& camera);

struct InitialGuessResult {
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
  bool ok = false;
  double rms_center_m = 0.0;  ///< RMS distance of the aligned centres [m]
  int num_correspondences = 0;
  std::string message;        ///< method used, or why it failed
  /// Another pose, far from this one, pairs the holes otherwise and fits nearly as well (a
  /// symmetric hole layout seen from too few poses); `ambiguity` says how far and how well.
  bool ambiguous = false;
  std::string ambiguity;
};

/// align_rigid's default weight of a direction pair against a point pair [m^2].
constexpr double kDirectionWeightM2 = 1.0;

/// Rigid alignment of point and direction correspondences (Kabsch/Umeyama without scale):
/// finds T minimising sum |T a_i - b_i|^2 + w sum |R u_i - v_i|^2. Needs >= 3 points in
/// general position, or >= 1 point and >= 2 non-parallel directions.
Eigen::Isometry3d align_rigid(const std::vector<Eigen::Vector3d>& points_a,
                              const std::vector<Eigen::Vector3d>& points_b,
                              const std::vector<Eigen::Vector3d>& directions_a = {},
                              const std::vector<Eigen::Vector3d>& directions_b = {},
                              double direction_weight_m2 = kDirectionWeightM2);

/// Closed-form T_camera_lidar from the per-hole data of the views (lidar_centers,
/// lidar_normals, image_ellipses). Views without that data are skipped. The LIDAR holes and
/// the image ellipses of a view may be listed in different orders: the pairing is searched
/// (the detectors' order, and every pairing of each view of 3-7 holes as a start pose, each
/// view then paired by position) and the pose whose centres reproject best is returned.
InitialGuessResult closed_form_initial_guess(const std::vector<TargetView>& views,
                                             const core::PinholeCamera& camera);

}  // namespace rgbdt::extrinsics
