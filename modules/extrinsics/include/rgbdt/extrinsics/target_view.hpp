#pragma once
/// \file
/// One placement of the circle target, seen by the LIDAR and by one camera: the input of
/// the edge alignment (paper Sec. 3.6). Filled from calib_targets detections (see
/// make_target_view()) or by hand in tests.
#include <Eigen/Core>
#include <opencv2/core/types.hpp>
#include <string>
#include <vector>

namespace rgbdt::extrinsics {

struct TargetView {
  /// Points of the fitted 3D circles (Algorithm 3), all holes [m], LIDAR frame.
  std::vector<Eigen::Vector3d> lidar_circle_points;
  /// Sub-pixel image edge points of the holes [px]; their distance field is Eq. (2).
  std::vector<Eigen::Vector2d> image_edge_points_px;
  /// Per hole, for the closed-form initial guess (same hole order in all three):
  std::vector<Eigen::Vector3d> lidar_centers;  ///< hole centres [m], LIDAR frame
  std::vector<Eigen::Vector3d> lidar_normals;  ///< unit board normals, LIDAR frame
  std::vector<cv::RotatedRect> image_ellipses; ///< hole ellipses [px] (distorted image)
  double radius_m = 0.0;                       ///< hole radius [m]
  int image_width = 0;                         ///< [px]
  int image_height = 0;                        ///< [px]
  std::string name;                            ///< e.g. "view 3", used in messages
};

}  // namespace rgbdt::extrinsics
