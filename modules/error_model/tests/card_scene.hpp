#pragma once
// The Sec. 4.4 scene shared by the card-band tests: a white card before a black cloth, a
// tilting-LIDAR scan of it and a camera image rendered by ray casting.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/error_model/coloring_band.hpp"

namespace rgbdt::error_model::test {

constexpr double kDeg = M_PI / 180.0;
constexpr float kWhite = 220.0f, kBlack = 20.0f;

/// The Sec. 4.4 scene in the LIDAR frame (x forward, z up): a white card facing the LIDAR,
/// rolled a few degrees as a hand-placed card is, and a black cloth 0.3 m behind it.
struct Scene {
  double depth_m = 5.0;
  Eigen::Vector3d card_centre;
  Eigen::Vector3d card_u, card_v;  // unit edge directions (right, up)
  double half_w = 0.6, half_h = 0.45;
  double gap_m = 0.3;
  float card_colour = kWhite, cloth_colour = kBlack;

  explicit Scene(double depth) : depth_m(depth), card_centre(depth, 0.15, 0.1) {
    const double roll = 4.0 * kDeg;
    card_u = Eigen::Vector3d(0.0, -std::cos(roll), std::sin(roll));
    card_v = Eigen::Vector3d(0.0, std::sin(roll), std::cos(roll));
  }
  /// Optional ground plane z = ground_z_m (pavement), as in rgbdt_sim's coloring setup.
  bool ground = false;
  double ground_z_m = -1.1;
  float ground_colour = 120.0f;

  /// Colour seen along the ray origin + s dir (first hit), or nothing (false).
  bool cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, Eigen::Vector3d* hit, float* colour) const {
    double best = std::numeric_limits<double>::infinity();
    if (ground && dir.z() < 0.0) {
      const double s = (ground_z_m - origin.z()) / dir.z();
      if (s > 0.0) {
        best = s;
        *colour = ground_colour;
      }
    }
    if (dir.x() > 0.0) {
      const double s_card = (depth_m - origin.x()) / dir.x();
      const Eigen::Vector3d d = origin + s_card * dir - card_centre;
      if (s_card < best && std::abs(d.dot(card_u)) <= half_w && std::abs(d.dot(card_v)) <= half_h) {
        best = s_card;
        *colour = card_colour;
      }
      const double s_cloth = (depth_m + gap_m - origin.x()) / dir.x();
      const Eigen::Vector3d b = origin + s_cloth * dir;
      if (s_cloth < best && std::abs(b.y() - card_centre.y()) <= 2.5 && std::abs(b.z() - card_centre.z()) <= 2.0) {
        best = s_cloth;
        *colour = cloth_colour;
      }
    }
    if (!std::isfinite(best)) return false;
    *hit = origin + best * dir;
    return true;
  }
};

inline core::PinholeCamera rgb_camera() {
  core::CameraIntrinsics k;
  k.camera_name = "rgb";
  k.width = 1288;
  k.height = 964;
  k.fx = 1335.054;
  k.fy = 1333.2;
  k.cx = 640.5;
  k.cy = 478.9;
  k.model = core::DistortionModel::kPlumbBob;
  k.distortion = {-0.05, 0.02, 0.0, 0.0, 0.0};
  return core::PinholeCamera(k);
}

inline Eigen::Isometry3d true_T_camera_lidar() {
  Eigen::Matrix3d R;
  R << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  // A small lateral baseline keeps the cloth's occlusion shadow behind the card edges
  // (baseline * gap / depth = 1.2 mm at 5 m) well below what is measured here.
  return core::make_transform(R, Eigen::Vector3d(0.02, -0.01, 0.05));
}

/// The camera image of the scene. Every ray the scans use outside the card meets the cloth,
/// so the image is the cloth's colour except in the card's bounding box (projected corners
/// plus a margin for distortion), which is ray cast pixel by pixel; this keeps the Newton
/// undistortion of every pixel, slow under sanitizers, to the part that matters.
inline GrayImage render(const Scene& scene, const core::PinholeCamera& camera, const Eigen::Isometry3d& T_camera_lidar) {
  GrayImage image{camera.width(), camera.height(), {}};
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, scene.cloth_colour);
  const Eigen::Isometry3d T_lidar_camera = T_camera_lidar.inverse();
  double u0 = image.width, u1 = 0.0, v0 = image.height, v1 = 0.0;
  for (double su : {-1.0, 1.0}) {
    for (double sv : {-1.0, 1.0}) {
      Eigen::Vector2d uv;
      const Eigen::Vector3d corner = scene.card_centre + su * scene.half_w * scene.card_u + sv * scene.half_h * scene.card_v;
      if (!camera.project(T_camera_lidar * corner, &uv)) continue;
      u0 = std::min(u0, uv.x());
      u1 = std::max(u1, uv.x());
      v0 = std::min(v0, uv.y());
      v1 = std::max(v1, uv.y());
    }
  }
  constexpr double kMarginPx = 40.0;
  const int ua = std::max(0, static_cast<int>(u0 - kMarginPx)), ub = std::min(image.width - 1, static_cast<int>(u1 + kMarginPx));
  const int va = std::max(0, static_cast<int>(v0 - kMarginPx)), vb = std::min(image.height - 1, static_cast<int>(v1 + kMarginPx));
  for (int v = va; v <= vb; ++v) {
    for (int u = ua; u <= ub; ++u) {
      const Eigen::Vector3d dir = T_lidar_camera.linear() * camera.unproject(Eigen::Vector2d(u, v));
      Eigen::Vector3d hit;
      float colour = 0.0f;
      if (scene.cast(T_lidar_camera.translation(), dir, &hit, &colour)) {
        image.pixels[static_cast<std::size_t>(v) * image.width + u] = colour;
      }
    }
  }
  return image;
}

/// A tilting scan of the scene: 0.25 deg beams (UTM-30LX), 0.2 deg between scan lines,
/// 1 cm range noise. With mixed_pixels, a beam whose next beam hits the other surface returns
/// a range somewhere in between (what a UTM-30LX does at depth edges).
inline std::vector<Eigen::Vector3d> scan(const Scene& scene, unsigned seed, bool mixed_pixels = false) {
  std::vector<Eigen::Vector3d> points;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  const double yaw_c = std::atan2(scene.card_centre.y(), scene.card_centre.x());
  const double pitch_c = std::atan2(scene.card_centre.z(), scene.card_centre.x());
  const double half_yaw = std::atan2(1.2, scene.depth_m), half_pitch = std::atan2(1.0, scene.depth_m);
  for (double pitch = pitch_c - half_pitch; pitch <= pitch_c + half_pitch; pitch += 0.2 * kDeg) {
    for (double yaw = -135.0 * kDeg; yaw <= 135.0 * kDeg; yaw += 0.25 * kDeg) {
      if (std::abs(yaw - yaw_c) > half_yaw) continue;
      const Eigen::Vector3d dir(std::cos(pitch) * std::cos(yaw), std::cos(pitch) * std::sin(yaw), std::sin(pitch));
      Eigen::Vector3d hit;
      float colour = 0.0f;
      if (!scene.cast(Eigen::Vector3d::Zero(), dir, &hit, &colour)) continue;
      if (mixed_pixels) {
        const double next = yaw + 0.25 * kDeg;
        const Eigen::Vector3d dir2(std::cos(pitch) * std::cos(next), std::cos(pitch) * std::sin(next), std::sin(pitch));
        Eigen::Vector3d hit2;
        float colour2 = 0.0f;
        if (scene.cast(Eigen::Vector3d::Zero(), dir2, &hit2, &colour2) && colour2 != colour) {
          const double r1 = hit.norm(), r2 = hit2.norm();
          points.push_back(dir * (r1 + std::uniform_real_distribution<double>(0.1, 0.9)(rng) * (r2 - r1)));
          continue;
        }
      }
      points.push_back(hit + noise(rng) * dir);
    }
  }
  return points;
}

}  // namespace rgbdt::error_model::test
