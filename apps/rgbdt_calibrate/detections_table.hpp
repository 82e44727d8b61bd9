#pragma once
// The detections of a calibration run as a table, one row per hole and view: the CSV file
// detections_<camera>.csv (or detections_lidar.csv of --lidar-only) and the same as a
// Markdown table for report.md.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/types.hpp>

namespace rgbdt::calibrate {

struct DetectionRow {
  int view = 0;  ///< index of the view in the session
  int hole = 0;  ///< index of the hole in the board's layout order
  Eigen::Vector3d lidar_center = Eigen::Vector3d::Zero();  ///< [m], LIDAR frame
  double lidar_radius_m = 0.0;
  bool radius_measured = false;  ///< false: the known radius (no free-radius fit)
  std::string lidar_method;      ///< LidarTargetDetection::edge_method
  std::optional<cv::RotatedRect> image_ellipse;  ///< [px], absent without a camera or a pairing
  std::optional<double> view_rms_px;             ///< residual of the view at the estimate
  std::optional<bool> used;                      ///< used by the solve
};

/// Header: view,hole,lidar_x_m,lidar_y_m,lidar_z_m,lidar_radius_m,radius_measured,image_u_px,
/// image_v_px,ellipse_major_px,ellipse_minor_px,ellipse_angle_deg,lidar_method,view_rms_px,used
/// (empty cells where a value does not apply).
std::string format_detections_csv(const std::vector<DetectionRow>& rows);
std::string format_detections_markdown(const std::vector<DetectionRow>& rows);

}  // namespace rgbdt::calibrate
