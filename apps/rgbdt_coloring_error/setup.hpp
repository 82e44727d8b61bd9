#pragma once
// The --setup mode: the coloring-error setup of paper Sec. 4.4 (card before cloth at several
// depths), measured automatically, as Tables 2 and 3.
#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace rgbdt::apps {

/// One placement of the card: a LIDAR cloud and one image per camera.
struct SetupView {
  std::string cloud;                          ///< absolute PCD path
  std::map<std::string, std::string> images;  ///< camera -> absolute PNG path
};

struct SetupSession {
  std::string directory;                          ///< absolute folder of session.yaml
  std::map<std::string, std::string> intrinsics;  ///< camera -> camera_info YAML
  std::vector<SetupView> views;
};

/// Reads session.yaml (or the folder holding it) in either layout of design.md:
///  - views: [{cloud: c.pcd, images: {rgb: a.png, thermal: b.png}}] (calibration layout;
///    the target entry, if any, is not needed), or
///  - lidar: {clouds: index.csv} with cameras' frames: index.csv (mapping layout), each
///    cloud paired with the nearest frame in time of every camera.
/// Throws rgbdt::core::Error naming the file, the key and what was expected.
SetupSession read_setup_session(const std::string& path);

struct SetupSettings {
  std::string calib_dir;
  std::string camera;  ///< only this camera (empty: every camera with extrinsics)
  std::vector<double> intrinsics_sigma;
  double lidar_noise_m = 0.02;
  /// Extrinsics covariance to use when the calibration file has none, or to override it
  /// (empty: the file's).
  std::optional<Eigen::Matrix<double, 6, 6>> extrinsics_covariance;
  /// What-if: colour with the calibration moved by this [rx ry rz tx ty tz] (rad, m) in the
  /// camera frame, T' = from_vector6(offset) * T (empty: as calibrated).
  std::optional<Eigen::Matrix<double, 6, 1>> extrinsics_offset;
  std::string report_dir;  ///< also write coloring_setup.md there (empty: stdout only)
  std::string config_yaml;  ///< the app's effective configuration, recorded in coloring_setup.md
};

/// Measures every view with every camera, prints the tables; returns the exit code.
int run_setup(const SetupSession& session, const SetupSettings& settings);

}  // namespace rgbdt::apps
