#include "rgbdt/sim/camera_sim.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace rgbdt::sim {

namespace {

// Key that changes across every edge the renderer must anti-alias: surface and region.
inline int surface_key(const std::optional<Hit>& hit) { return hit ? hit->primitive * 4 + hit->region : -1; }

void check(const std::string& why) {
  if (!why.empty()) throw std::invalid_argument(why);
}

}  // namespace

std::string RenderOptions::validate() const {
  if (supersampling < 1 || supersampling > 32) {
    return "supersampling " + std::to_string(supersampling) + " must be in [1, 32]";
  }
  return {};
}

std::string RgbCameraOptions::validate() const {
  std::ostringstream os;
  if (const std::string r = render.validate(); !r.empty()) os << r;
  else if (!(exposure_gain > 0.0)) os << "exposure_gain " << exposure_gain << " must be positive";
  else if (!(blur_sigma_px >= 0.0)) os << "blur_sigma_px " << blur_sigma_px << " must be >= 0";
  else if (!(noise_sigma_dn >= 0.0)) os << "noise_sigma_dn " << noise_sigma_dn << " must be >= 0";
  else if (!(exposure_time_s >= 0.0)) os << "exposure_time_s " << exposure_time_s << " must be >= 0";
  return os.str();
}

std::string ThermalCameraOptions::validate() const {
  std::ostringstream os;
  if (const std::string r = render.validate(); !r.empty()) os << r;
  else if (!(kelvin_per_count > 0.0)) os << "kelvin_per_count " << kelvin_per_count << " must be positive";
  else if (!(blur_sigma_px >= 0.0)) os << "blur_sigma_px " << blur_sigma_px << " must be >= 0";
  else if (!(netd_k >= 0.0) || !(fpn_pixel_sigma_k >= 0.0) || !(fpn_column_sigma_k >= 0.0)) os << "noise levels must be >= 0";
  else if (max_count < 1 || max_count > 65535) os << "max_count " << max_count << " must be in [1, 65535]";
  else if (!(exposure_time_s >= 0.0)) os << "exposure_time_s " << exposure_time_s << " must be >= 0";
  return os.str();
}

Eigen::Vector3d shade_rgb(const Scene& scene, const Hit& hit) {
  const Environment& env = scene.environment;
  const double sun = std::max(0.0, hit.normal.dot(env.sun_direction_world.normalized()));
  return scene.material(hit.material).albedo_rgb * (env.ambient + env.sun_irradiance * sun);
}

double apparent_temperature_k(const Scene& scene, const Hit& hit) {
  // Linear in temperature (the radiometric map is linear too): emitted plus reflected sky.
  const Material& m = scene.material(hit.material);
  return m.emissivity * m.temperature_k + (1.0 - m.emissivity) * scene.environment.sky_temperature_k;
}

CameraRenderer::CameraRenderer(const core::PinholeCamera& camera) : camera_(camera) {
  const int w = camera_.width(), h = camera_.height();
  centre_rays_.resize(static_cast<size_t>(w) * h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      centre_rays_[static_cast<size_t>(v) * w + u] = camera_.unproject(Eigen::Vector2d(u, v)).normalized().cast<float>();
    }
  }
}

template <typename Shade>
cv::Mat CameraRenderer::render(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                               const RenderOptions& options, int channels, Shade shade) const {
  check(options.validate());
  const int w = camera_.width(), h = camera_.height();
  const Eigen::Matrix3d R = T_world_camera.linear();
  const Eigen::Vector3d o = T_world_camera.translation();
  cv::Mat out(h, w, CV_32FC(channels));
  std::vector<int> keys(static_cast<size_t>(w) * h);
  auto put = [&](int u, int v, const Eigen::Vector3d& value) {
    float* px = out.ptr<float>(v) + static_cast<size_t>(u) * channels;
    for (int c = 0; c < channels; ++c) px[c] = static_cast<float>(value[c]);
  };
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const std::optional<Hit> hit = scene.intersect(o, R * centre_rays_[i].cast<double>());
      keys[i] = surface_key(hit);
      put(u, v, shade(hit));
    }
  }
  const int n = options.supersampling;
  if (n <= 1) return out;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const int key = keys[static_cast<size_t>(v) * w + u];
      bool edge = false;
      for (int dv = -1; dv <= 1 && !edge; ++dv) {
        for (int du = -1; du <= 1 && !edge; ++du) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          edge = keys[static_cast<size_t>(vv) * w + uu] != key;
        }
      }
      if (!edge) continue;
      // Box filter over the pixel's area [u - 0.5, u + 0.5] x [v - 0.5, v + 0.5].
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int j = 0; j < n; ++j) {
        for (int k = 0; k < n; ++k) {
          const Eigen::Vector2d px(u - 0.5 + (k + 0.5) / n, v - 0.5 + (j + 0.5) / n);
          sum += shade(scene.intersect(o, R * camera_.unproject(px)));
        }
      }
      put(u, v, sum / (n * n));
    }
  }
  return out;
}

cv::Mat CameraRenderer::render_radiance(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                                        const RenderOptions& options) const {
  return render(scene, T_world_camera, options, 3, [&](const std::optional<Hit>& hit) -> Eigen::Vector3d {
    return hit ? shade_rgb(scene, *hit) : scene.environment.sky_rgb;
  });
}

cv::Mat CameraRenderer::render_temperature(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                                           const RenderOptions& options) const {
  return render(scene, T_world_camera, options, 1, [&](const std::optional<Hit>& hit) -> Eigen::Vector3d {
    const double t = hit ? apparent_temperature_k(scene, *hit) : scene.environment.sky_temperature_k;
    return Eigen::Vector3d(t, 0.0, 0.0);
  });
}

cv::Mat CameraRenderer::render_rgb(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                                   const RgbCameraOptions& options, std::mt19937_64& rng) const {
  check(options.validate());
  cv::Mat radiance = render_radiance(scene, T_world_camera, options.render);
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(radiance, radiance, cv::Size(0, 0), options.blur_sigma_px, options.blur_sigma_px,
                     cv::BORDER_REPLICATE);
  }
  std::normal_distribution<double> noise(0.0, 1.0);
  cv::Mat bgr(radiance.rows, radiance.cols, CV_8UC3);
  for (int v = 0; v < radiance.rows; ++v) {
    const float* in = radiance.ptr<float>(v);
    auto* px = bgr.ptr<unsigned char>(v);
    for (int u = 0; u < radiance.cols; ++u) {
      for (int c = 0; c < 3; ++c) {
        double dn = 255.0 * options.exposure_gain * in[3 * u + c];
        if (options.noise_sigma_dn > 0.0) dn += options.noise_sigma_dn * noise(rng);
        px[3 * u + (2 - c)] = static_cast<unsigned char>(std::clamp(std::lround(dn), 0L, 255L));
      }
    }
  }
  return bgr;
}

cv::Mat CameraRenderer::render_thermal(const Scene& scene, const Eigen::Isometry3d& T_world_camera,
                                       const ThermalCameraOptions& options, std::mt19937_64& rng) const {
  check(options.validate());
  cv::Mat kelvin = render_temperature(scene, T_world_camera, options.render);
  if (options.blur_sigma_px > 0.0) {
    cv::GaussianBlur(kelvin, kelvin, cv::Size(0, 0), options.blur_sigma_px, options.blur_sigma_px,
                     cv::BORDER_REPLICATE);
  }
  // The fixed pattern is a property of this camera: same seed, same pattern in every frame.
  std::mt19937_64 fpn_rng(options.fpn_seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::vector<double> column(static_cast<size_t>(kelvin.cols));
  for (double& c : column) c = options.fpn_column_sigma_k * unit(fpn_rng);
  cv::Mat counts(kelvin.rows, kelvin.cols, CV_16UC1);
  for (int v = 0; v < kelvin.rows; ++v) {
    const float* in = kelvin.ptr<float>(v);
    auto* out = counts.ptr<std::uint16_t>(v);
    for (int u = 0; u < kelvin.cols; ++u) {
      double t = in[u] + column[static_cast<size_t>(u)] + options.fpn_pixel_sigma_k * unit(fpn_rng);
      if (options.netd_k > 0.0) t += options.netd_k * unit(rng);
      const long c = std::lround((t - options.offset_k) / options.kelvin_per_count);
      out[u] = static_cast<std::uint16_t>(std::clamp(c, 0L, static_cast<long>(options.max_count)));
    }
  }
  return counts;
}

}  // namespace rgbdt::sim
