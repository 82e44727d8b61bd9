#pragma once
/// \file
/// First-order propagation of every error that moves the colour of a LIDAR point: LIDAR
/// range / beam-angle / tilt-angle noise, the camera intrinsics covariance and the
/// camera-LIDAR extrinsics covariance, to
///   (a) the covariance of the pixel the point is coloured from, and
///   (b) the metric mis-colouring distance on the surface: the pixel error back-projected
///       (with the true calibration) onto the surface the point lies on. This is how far
///       from the point the surface patch that lends it its colour is, i.e. the width of
///       the mis-coloured band along an edge (paper Sec. 4.4, Fig. 12).
/// The paper (Sec. 4.3) treats one source at a time, the x axis only, no distortion and a
/// one-pixel threshold; this model is general: both axes, any pixel and depth, any surface
/// orientation, correlated sources, with a per-source breakdown.
///
/// Conventions.
/// - Intrinsics covariance: order fx fy cx cy, optionally followed by the distortion
///   coefficients of the model (plumb_bob k1 k2 p1 p2 k3; equidistant k1 k2 k3 k4), e.g.
///   the squared standard deviations that OpenCV's calibrateCameraExtended reports.
/// - Extrinsics covariance (core::Extrinsics::covariance): the covariance of the 6-vector
///   v = core::to_vector6(T_camera_lidar) = [rx ry rz tx ty tz] that the solvers estimate
///   (core/transform.hpp), so T' = core::from_vector6(v + dv). With
///   ExtrinsicsPerturbation::kLeft it is instead the covariance of a small motion of the
///   camera frame: T' = from_vector6(dv) * T (rotation about, and translation along, the
///   camera axes).
/// - LIDAR geometry follows core/tilt_rig.hpp: p_lidar = Ry(phi) T_axis_scanner
///   [r cos(theta), r sin(theta), 0]; range noise acts along the beam, beam-angle noise in
///   the scan plane, tilt noise about the tilt axis.
/// Jacobians are exact derivatives of core::project_generic (by ceres::Jet); monte_carlo()
/// re-projects without linearising and is what the tests compare against.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::error_model {

/// Measurement noise of a (tilting) 2D LIDAR, 1 sigma.
struct LidarNoise {
  double range_sigma_m = 0.02;        ///< range noise [m] (UTM-30LX: 0.01-0.03)
  double beam_angle_sigma_rad = 0.0;  ///< in-scan beam direction noise [rad]
  double tilt_angle_sigma_rad = 0.0;  ///< tilt angle noise (encoder resolution, timing) [rad]
  std::string validate() const;       ///< empty when valid, else the reason
};

/// How ErrorSources::extrinsics_covariance is to be read (see the file comment).
enum class ExtrinsicsPerturbation {
  kVector6,  ///< covariance of v = to_vector6(T_camera_lidar) (what the solvers estimate)
  kLeft,     ///< covariance of dv with T' = from_vector6(dv) * T_camera_lidar
};

/// Everything uncertain about colouring one LIDAR point with one camera.
struct ErrorSources {
  core::CameraIntrinsics intrinsics;
  /// fx fy cx cy [+ distortion]: 4x4 or (4 + distortion_size)^2 [px^2, 1]; empty = exact.
  Eigen::MatrixXd intrinsics_covariance;
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
  core::Matrix6d extrinsics_covariance = core::Matrix6d::Zero();  ///< [rad^2, m^2]
  ExtrinsicsPerturbation extrinsics_perturbation = ExtrinsicsPerturbation::kVector6;
  LidarNoise lidar;
  core::TiltRig rig;  ///< where the beams start and about which axis the scanner tilts
  /// Empty when usable, else the reason (sizes, symmetry, positive semi-definiteness).
  std::string validate() const;
};

/// The error sources of the per-source breakdown. kTotal is all of them at once, with the
/// rotation-translation cross-covariance (so it can differ from the sum of the others).
enum class Source { kLidar = 0, kIntrinsics, kRotation, kTranslation, kTotal };
constexpr int kNumSources = 5;
const char* to_string(Source source);  ///< "lidar", "intrinsics", "rotation", ...
/// Human-readable name for tables and plot legends ("LIDAR noise", ...).
const char* display_name(Source source);

/// One source's effect.
struct SourceError {
  Eigen::Matrix2d pixel_covariance = Eigen::Matrix2d::Zero();    ///< image u, v [px^2]
  Eigen::Matrix2d surface_covariance = Eigen::Matrix2d::Zero();  ///< surface x, y [m^2]
  double pixel_sigma_u_px() const;
  double pixel_sigma_v_px() const;
  double pixel_rms_px() const;       ///< sqrt(trace), the RMS pixel displacement [px]
  double surface_sigma_x_m() const;  ///< along the surface x axis [m]
  double surface_sigma_y_m() const;  ///< along the surface y axis [m]
  double surface_rms_m() const;      ///< RMS mis-colouring distance [m]
};

struct ColoringErrorPrediction {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();               ///< true pixel [px]
  Eigen::Vector3d point_camera = Eigen::Vector3d::Zero();        ///< [m]
  Eigen::Vector3d point_lidar = Eigen::Vector3d::Zero();         ///< [m]
  Eigen::Vector3d normal_camera = -Eigen::Vector3d::UnitZ();     ///< surface normal
  /// Surface axes in the camera frame: x is the camera x axis projected onto the surface,
  /// y completes it (the camera y axis for a surface facing the camera).
  Eigen::Vector3d surface_x_camera = Eigen::Vector3d::UnitX();
  Eigen::Vector3d surface_y_camera = Eigen::Vector3d::UnitY();
  std::array<SourceError, kNumSources> sources;
  int samples = 0;  ///< Monte Carlo samples per source (0 for the first-order model)

  const SourceError& operator[](Source s) const { return sources[static_cast<int>(s)]; }
  SourceError& operator[](Source s) { return sources[static_cast<int>(s)]; }
};

/// The model for one camera and one LIDAR. Immutable; copies are cheap enough.
class ColoringErrorModel {
 public:
  /// Throws std::invalid_argument with the reason when sources.validate() fails.
  explicit ColoringErrorModel(const ErrorSources& sources);

  const ErrorSources& sources() const { return sources_; }

  /// The point at camera depth depth_m [m] on the ray of `pixel` [px], on a surface with
  /// the given normal (camera frame; default: facing the camera). Throws
  /// std::invalid_argument when depth_m <= 0, the surface is seen edge-on, or the LIDAR
  /// geometry of core::TiltRig cannot reach the point.
  ColoringErrorPrediction predict(const Eigen::Vector2d& pixel, double depth_m,
                                  const Eigen::Vector3d& normal_camera = -Eigen::Vector3d::UnitZ()) const;

  /// The same for a point given in the LIDAR frame [m].
  ColoringErrorPrediction predict_point(const Eigen::Vector3d& point_lidar,
                                        const Eigen::Vector3d& normal_camera = -Eigen::Vector3d::UnitZ()) const;

  /// Monte Carlo estimate of the same quantities: for each source (and all together) draws
  /// `samples` Gaussian perturbations, re-projects exactly and back-projects onto the
  /// surface; covariances are the sample covariances. Deterministic for a given seed.
  ColoringErrorPrediction monte_carlo(const Eigen::Vector2d& pixel, double depth_m,
                                      const Eigen::Vector3d& normal_camera, int samples,
                                      std::uint64_t seed = 1) const;

  /// The LIDAR point covariance [m^2, LIDAR frame] from range, beam and tilt noise.
  Eigen::Matrix3d lidar_point_covariance(const Eigen::Vector3d& point_lidar) const;

 private:
  ErrorSources sources_;
  core::PinholeCamera camera_;
  std::array<double, 5> distortion_{};  ///< padded coefficients
  core::Vector6d v0_;                   ///< to_vector6(T_camera_lidar)
};

/// The band of mis-coloured surface one expects along an edge with the given direction
/// from an error of covariance `surface_covariance` [m^2]: the 1-sigma displacement
/// across the edge, i.e. perpendicular to `edge_direction` (surface x, y coordinates).
double across_edge_sigma_m(const Eigen::Matrix2d& surface_covariance,
                           const Eigen::Vector2d& edge_direction);

}  // namespace rgbdt::error_model
