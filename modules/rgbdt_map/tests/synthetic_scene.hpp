#pragma once
// Synthetic scenes for rgbdt_map's tests and benchmark: boxes and planes with smooth colour
// and temperature textures, a tilting 2D LIDAR (per-beam times as in
// rgbdt/core/tilt_rig.hpp) and ray-cast camera images, so colours, temperatures and
// visibility are known exactly.
#include <opencv2/core.hpp>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/camera.hpp"

namespace rgbdt::test {

struct Surface {
  enum Kind { kPlane, kBox } kind = kPlane;
  Eigen::Vector3d normal{1, 0, 0};  // plane: n.x = offset
  double offset = 0.0;
  Eigen::Vector3d box_min{0, 0, 0}, box_max{0, 0, 0};
  std::array<double, 3> base_rgb{128, 128, 128};
  double temperature_k = 290.0;
};

struct Hit {
  double distance = std::numeric_limits<double>::infinity();
  int surface = -1;
};

class Scene {
 public:
  std::vector<Surface> surfaces;

  Hit cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const {
    Hit best;
    for (std::size_t s = 0; s < surfaces.size(); ++s) {
      const Surface& f = surfaces[s];
      double d = std::numeric_limits<double>::infinity();
      if (f.kind == Surface::kPlane) {
        const double denom = f.normal.dot(dir);
        if (std::abs(denom) > 1e-12) {
          const double t = (f.offset - f.normal.dot(origin)) / denom;
          if (t > 1e-6) d = t;
        }
      } else {
        double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
        bool ok = true;
        for (int a = 0; a < 3 && ok; ++a) {
          if (std::abs(dir[a]) < 1e-12) {
            ok = origin[a] >= f.box_min[a] && origin[a] <= f.box_max[a];
            continue;
          }
          double ta = (f.box_min[a] - origin[a]) / dir[a];
          double tb = (f.box_max[a] - origin[a]) / dir[a];
          if (ta > tb) std::swap(ta, tb);
          t0 = std::max(t0, ta);
          t1 = std::min(t1, tb);
          ok = t0 <= t1;
        }
        if (ok && t0 > 1e-6) d = t0;
      }
      if (d < best.distance) best = {d, static_cast<int>(s)};
    }
    return best;
  }

  // Smooth texture of a surface point: base colour modulated by position, so a wrong
  // surface or a wrong place on the right surface both show.
  std::array<double, 3> color(int surface, const Eigen::Vector3d& p) const {
    const auto& b = surfaces[surface].base_rgb;
    return {b[0] + 25.0 * std::sin(1.3 * p.y()), b[1] + 25.0 * std::sin(1.7 * p.z()),
            b[2] + 25.0 * std::cos(0.9 * (p.x() + p.y()))};
  }
  double temperature_k(int surface, const Eigen::Vector3d& p) const {
    return surfaces[surface].temperature_k + 1.5 * std::sin(0.8 * p.y() + 0.5 * p.z());
  }
};

/// A box in front of a wall, on a ground plane (all in the LIDAR frame: x forward, z up).
inline Scene box_wall_scene() {
  Scene scene;
  Surface wall;
  wall.normal = {1, 0, 0};
  wall.offset = 6.0;
  wall.base_rgb = {200, 70, 60};
  wall.temperature_k = 288.0;
  Surface ground;
  ground.normal = {0, 0, 1};
  ground.offset = -1.0;
  ground.base_rgb = {70, 180, 80};
  ground.temperature_k = 300.0;
  Surface box;
  box.kind = Surface::kBox;
  box.box_min = {2.5, -0.5, -1.0};
  box.box_max = {3.2, 0.4, 0.45};
  box.base_rgb = {60, 80, 200};
  box.temperature_k = 315.0;
  scene.surfaces = {wall, ground, box};
  return scene;
}

/// A yard: ground, two side walls, a far wall and boxes of several sizes, so that all six
/// degrees of freedom of a registration are constrained.
inline Scene structured_scene() {
  Scene scene;
  auto plane = [](Eigen::Vector3d n, double offset, std::array<double, 3> rgb, double kelvin) {
    Surface s;
    s.normal = n;
    s.offset = offset;
    s.base_rgb = rgb;
    s.temperature_k = kelvin;
    return s;
  };
  auto box = [](Eigen::Vector3d lo, Eigen::Vector3d hi, std::array<double, 3> rgb, double kelvin) {
    Surface s;
    s.kind = Surface::kBox;
    s.box_min = lo;
    s.box_max = hi;
    s.base_rgb = rgb;
    s.temperature_k = kelvin;
    return s;
  };
  scene.surfaces = {plane({0, 0, 1}, -1.0, {90, 90, 90}, 295.0),  plane({0, 1, 0}, 5.0, {180, 60, 50}, 290.0),
                    plane({0, 1, 0}, -6.0, {60, 150, 60}, 292.0), plane({1, 0, 0}, 40.0, {200, 200, 80}, 289.0),
                    box({4, 1.5, -1}, {5, 2.5, 0.8}, {30, 60, 200}, 310.0),
                    box({7, -3, -1}, {8.5, -2, 0.3}, {200, 120, 30}, 305.0),
                    box({11, 0.5, -1}, {11.6, 1.5, 1.8}, {120, 30, 160}, 300.0),
                    box({15, -1.5, -1}, {17, -0.8, 0.5}, {30, 160, 160}, 298.0),
                    box({21, 2, -1}, {22, 4, 2.5}, {160, 160, 30}, 301.0),
                    box({26, -4, -1}, {27, -2.5, 1.0}, {100, 100, 200}, 299.0),
                    box({2.5, -4.5, -1}, {3.5, -3.5, 2.0}, {200, 200, 200}, 296.0)};
  return scene;
}

struct TiltScanOptions {
  int scans = 24;                 // scan lines per tilt
  double tilt_min_rad = -0.45;    // tilt < 0 pitches up
  double tilt_max_rad = 0.35;
  int beams = 1081;
  double aperture_rad = 270.0 * M_PI / 180.0;
  double scan_period_s = 0.025;
  int steps = 1440;
  double range_max_m = 30.0;
  double range_noise_m = 0.0;
  unsigned seed = 1;
  /// false: the tilt sweeps from tilt_min_rad (up) to tilt_max_rad (down); true: back up, as
  /// every other tilt of a tilt motor that sweeps to and fro.
  bool upward = false;
};

/// One tilt as the assembler delivers it. `pose_at(t)` gives T_world_lidar at time t (from
/// the cloud's start); each point is expressed in the LIDAR frame at its own time.
inline cloud::Cloud scan_tilt(const Scene& scene_world, const TiltScanOptions& o,
                              const std::function<Eigen::Isometry3d(double)>& pose_at = {}) {
  cloud::Cloud cloud;
  std::uint32_t state = o.seed * 2654435761u + 1u;
  auto gauss = [&]() {  // Box-Muller on a tiny LCG keeps the scene reproducible everywhere
    auto uni = [&]() {
      state = state * 1664525u + 1013904223u;
      return (static_cast<double>(state >> 8) + 0.5) / 16777216.0;
    };
    return std::sqrt(-2.0 * std::log(uni())) * std::cos(2.0 * M_PI * uni());
  };
  for (int s = 0; s < o.scans; ++s) {
    for (int i = 0; i < o.beams; ++i) {
      const double t = s * o.scan_period_s + i * o.scan_period_s / o.steps;
      const double swept = (s * o.beams + i) / static_cast<double>(o.scans * o.beams);
      const double phi = o.upward ? o.tilt_max_rad - (o.tilt_max_rad - o.tilt_min_rad) * swept
                                  : o.tilt_min_rad + (o.tilt_max_rad - o.tilt_min_rad) * swept;
      const double theta = -0.5 * o.aperture_rad + o.aperture_rad * i / (o.beams - 1);
      const Eigen::Vector3d dir_lidar =
          Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitY()) * Eigen::Vector3d(std::cos(theta), std::sin(theta), 0);
      const Eigen::Isometry3d T_world_lidar = pose_at ? pose_at(t) : Eigen::Isometry3d::Identity();
      const Hit hit = scene_world.cast(T_world_lidar.translation(), T_world_lidar.linear() * dir_lidar);
      if (hit.surface < 0 || hit.distance > o.range_max_m) continue;
      const double range = hit.distance + (o.range_noise_m > 0 ? o.range_noise_m * gauss() : 0.0);
      const Eigen::Vector3d p = dir_lidar * range;
      cloud::PointXYZIRT q;
      q.x = static_cast<float>(p.x());
      q.y = static_cast<float>(p.y());
      q.z = static_cast<float>(p.z());
      q.intensity = 100.0f;
      q.ring = static_cast<std::uint16_t>(s);
      q.t = static_cast<float>(t);
      cloud.push_back(q);
    }
  }
  return cloud;
}

/// Ray-cast images of a camera at pose T_world_camera: BGR colour (8UC3), 16-bit counts
/// of kelvin / kelvin_per_count, and the id of the surface each pixel sees (-1: none).
struct RenderedView {
  cv::Mat bgr, counts, surface_id;
};
inline RenderedView render(const Scene& scene_world, const core::PinholeCamera& camera,
                           const Eigen::Isometry3d& T_world_camera, double kelvin_per_count) {
  RenderedView v;
  v.bgr = cv::Mat(camera.height(), camera.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  v.counts = cv::Mat(camera.height(), camera.width(), CV_16UC1, cv::Scalar(0));
  v.surface_id = cv::Mat(camera.height(), camera.width(), CV_32SC1, cv::Scalar(-1));
  for (int y = 0; y < camera.height(); ++y) {
    for (int x = 0; x < camera.width(); ++x) {
      const Eigen::Vector3d ray = camera.unproject(Eigen::Vector2d(x, y)).normalized();
      const Eigen::Vector3d dir = T_world_camera.linear() * ray;
      const Hit hit = scene_world.cast(T_world_camera.translation(), dir);
      if (hit.surface < 0) continue;
      const Eigen::Vector3d p = T_world_camera.translation() + hit.distance * dir;
      const auto c = scene_world.color(hit.surface, p);
      v.bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(c[2]), cv::saturate_cast<uchar>(c[1]),
                                            cv::saturate_cast<uchar>(c[0]));
      v.counts.at<std::uint16_t>(y, x) =
          cv::saturate_cast<std::uint16_t>(std::lround(scene_world.temperature_k(hit.surface, p) / kelvin_per_count));
      v.surface_id.at<int>(y, x) = hit.surface;
    }
  }
  return v;
}

/// Camera frame from "x right, y down, z forward" looking along the LIDAR's +x.
inline Eigen::Matrix3d R_lidar_camera_forward() {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0, -1, 0);
  R.col(1) = Eigen::Vector3d(0, 0, -1);
  R.col(2) = Eigen::Vector3d(1, 0, 0);
  return R;
}

inline core::CameraIntrinsics test_intrinsics(int width, int height, double f, double k1 = -0.05) {
  core::CameraIntrinsics k;
  k.camera_name = "test";
  k.width = width;
  k.height = height;
  k.fx = k.fy = f;
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  k.model = core::DistortionModel::kPlumbBob;
  k.distortion = {k1, 0.01, 0.0005, -0.0003, 0.0};
  return k;
}

}  // namespace rgbdt::test
