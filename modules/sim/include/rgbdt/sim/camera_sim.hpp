#pragma once
/// \file
/// Camera rendering by ray casting through pixels.
///
/// Each pixel is first sampled at its centre. Pixels whose 8-neighbourhood sees another
/// surface or region (an edge passes through them) are re-rendered with an N x N grid of
/// sub-samples over the pixel's area (box filter), so an edge lands in the image at
/// sub-pixel accuracy: the 50 % crossing of a step edge is where the edge really is.
/// A sub-sample at pixel (u, v) casts the ray PinholeCamera::unproject((u, v)), so the
/// lens distortion is rendered exactly. Optics blur (Gaussian) and sensor noise follow.
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/sim/scene.hpp"

namespace rgbdt::sim {

struct RenderOptions {
  int supersampling = 8;  ///< N: N x N sub-samples in edge pixels; 1 renders pixel centres only
  std::string validate() const;
};

/// Visible-light camera (8-bit colour, BGR order as OpenCV writes PNGs).
struct RgbCameraOptions {
  RenderOptions render;
  double exposure_gain = 1.0;     ///< scales radiance to grey levels (255 = white in full sun)
  double blur_sigma_px = 0.35;    ///< optics blur, Gaussian [px]; 0 = none
  double noise_sigma_dn = 1.5;    ///< read noise [grey levels]
  double exposure_time_s = 0.004; ///< the image is stamped at the middle of the exposure
  std::string validate() const;
};

/// Uncooled LWIR camera (FLIR Tau2 like): 16-bit raw counts with a linear radiometric map
/// kelvin = offset_k + kelvin_per_count * counts.
struct ThermalCameraOptions {
  RenderOptions render;
  double kelvin_per_count = 0.04;
  double offset_k = 0.0;
  double blur_sigma_px = 0.7;        ///< optics blur [px]
  double netd_k = 0.05;              ///< temporal noise (NETD) [K]
  double fpn_pixel_sigma_k = 0.03;   ///< fixed-pattern offset per pixel [K]
  double fpn_column_sigma_k = 0.02;  ///< fixed-pattern offset per column [K]
  std::uint64_t fpn_seed = 7;        ///< the fixed pattern belongs to the camera, not the frame
  int max_count = 16383;             ///< 14-bit core
  double exposure_time_s = 0.008;    ///< microbolometer integration (time constant)
  std::string validate() const;
};

/// Renders one camera. Keeps the centre ray of every pixel (computed once), so render
/// many frames with one CameraRenderer.
class CameraRenderer {
 public:
  /// Throws std::invalid_argument if the intrinsics are invalid.
  explicit CameraRenderer(const core::PinholeCamera& camera);
  const core::PinholeCamera& camera() const { return camera_; }

  /// Noise-free linear RGB radiance per pixel (CV_32FC3, [0, 1] for white in full sun,
  /// channel order R G B), supersampled at edges. T_world_camera: camera pose.
  cv::Mat render_radiance(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                          const RenderOptions& options) const;
  /// Noise-free apparent temperature per pixel [K] (CV_32FC1), supersampled at edges.
  cv::Mat render_temperature(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                             const RenderOptions& options) const;

  /// A full RGB frame: radiance, exposure, blur, noise, 8-bit BGR (CV_8UC3).
  cv::Mat render_rgb(const Scene& scene, const Eigen::Isometry3d& T_world_camera, const RgbCameraOptions& options,
                     std::mt19937_64& rng) const;
  /// A full thermal frame: temperature, blur, fixed-pattern and temporal noise, counts (CV_16UC1).
  cv::Mat render_thermal(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                         const ThermalCameraOptions& options, std::mt19937_64& rng) const;

 private:
  template <typename Shade>
  cv::Mat render(const Scene& scene, const Eigen::Isometry3d& T_world_camera, const RenderOptions& options,
                 int channels, Shade shade) const;

  core::PinholeCamera camera_;
  std::vector<Eigen::Vector3f> centre_rays_;  ///< unit rays, camera frame, row-major
};

/// Radiance of a surface point for the RGB camera (Lambertian, sun + sky ambient), R G B.
Eigen::Vector3d shade_rgb(const Scene& scene, const Hit& hit);
/// Apparent temperature of a hit [K]: emissivity-weighted surface and reflected sky.
double apparent_temperature_k(const Scene& scene, const Hit& hit);

}  // namespace rgbdt::sim
