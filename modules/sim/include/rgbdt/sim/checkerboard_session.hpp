#pragma once
/// \file
/// Intrinsic-calibration image sets of the paper's melamine checkerboard (Sec. 3.1): black
/// and white 2-inch squares; in the sun the black squares are warmer than the white ones,
/// so the pattern shows in the thermal band too.
///
/// Layout written to DIR:
///   <camera>/000.png ...          8-bit colour (rgb) or 16-bit counts (thermal)
///   <camera>.yaml                 true intrinsics (ROS camera_info), also true_calib/<camera>.yaml
///   ground_truth.yaml             board geometry, per view T_camera_board and the true
///                                 inner-corner pixels (row-major from the board's top-left)
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/sim/rig.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

struct CheckerboardSessionOptions {
  std::string camera = "thermal";  ///< "rgb" or "thermal"
  int views = 0;                   ///< 0: 40 for thermal (the paper's count), 20 for rgb
  std::uint64_t seed = 1;
  double noise_scale = 1.0;        ///< multiplies image noise / NETD / fixed pattern
  int squares_x = 9;               ///< squares across (inner corners: squares_x - 1)
  int squares_y = 7;               ///< squares down (inner corners: squares_y - 1)
  double square_m = 0.0508;        ///< 2 inches
  double min_distance_m = 0.0;     ///< 0: 0.7 m (thermal) / 1.0 m (rgb)
  double max_distance_m = 0.0;     ///< 0: 1.6 m (thermal) / 2.2 m (rgb)
  double max_tilt_deg = 40.0;      ///< board rotation away from fronto-parallel
  int supersampling = 8;
  TimeOfDay time_of_day = TimeOfDay::kDay;  ///< in the sun: black squares ~8 K warmer
  RigSpec rig;                     ///< intrinsics and camera options are taken from here
  std::string validate() const;
};

struct CheckerboardViewTruth {
  Eigen::Isometry3d T_camera_board;             ///< board frame: centre, x right, y up, z to the camera
  std::vector<Eigen::Vector2d> corners_px;      ///< true inner corners, row-major from the top-left
};

struct CheckerboardSessionResult {
  std::string directory;
  core::CameraIntrinsics intrinsics;
  std::vector<Eigen::Vector3d> corners_board;   ///< inner corners in the board frame [m]
  std::vector<CheckerboardViewTruth> views;
};

/// Inner-corner positions in the board frame, row-major from the top-left (as seen from
/// the camera): corner (i, j) at (x0 + (i + 1) s, y0 - (j + 1) s, 0) with (x0, y0) the
/// pattern's top-left corner, the pattern centred on the board.
std::vector<Eigen::Vector3d> checkerboard_corners(int squares_x, int squares_y, double square_m);

/// Writes the image set; throws std::invalid_argument for bad options, core::Error on I/O.
CheckerboardSessionResult write_checkerboard_session(const std::string& out_dir,
                                                     const CheckerboardSessionOptions& options);

}  // namespace rgbdt::sim
