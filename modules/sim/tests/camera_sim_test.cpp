// Rendered images against the true geometry: hole edges at sub-pixel accuracy, noise and
// radiometry at their configured levels.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/calibration_session.hpp"
#include "rgbdt/sim/camera_sim.hpp"
#include "rgbdt/sim/rig.hpp"

namespace rgbdt::sim {
namespace {

double bilinear(const cv::Mat& img, const Eigen::Vector2d& p) {
  const int u0 = static_cast<int>(std::floor(p.x())), v0 = static_cast<int>(std::floor(p.y()));
  const double a = p.x() - u0, b = p.y() - v0;
  auto at = [&](int u, int v) { return static_cast<double>(img.at<float>(v, u)); };
  return (1 - a) * (1 - b) * at(u0, v0) + a * (1 - b) * at(u0 + 1, v0) + (1 - a) * b * at(u0, v0 + 1) +
         a * b * at(u0 + 1, v0 + 1);
}

struct EdgeErrors {
  double rms_px = 0.0, max_px = 0.0;
  int count = 0;
};

// For points of the true hole edge (projected with the true extrinsics and intrinsics),
// finds the 50 % crossing of the rendered image along the line from the projected hole
// centre through the point, and returns its distance from the projected point.
EdgeErrors measure_hole_edges(const cv::Mat& image, const core::PinholeCamera& camera,
                              const Eigen::Isometry3d& T_camera_lidar, const Eigen::Isometry3d& T_lidar_board,
                              double radius_m) {
  EdgeErrors e;
  double sum2 = 0.0;
  Eigen::Vector2d centre;
  EXPECT_TRUE(camera.project(T_camera_lidar * T_lidar_board.translation(), &centre));
  for (int k = 0; k < 90; ++k) {
    const double a = k * 4.0 * M_PI / 180.0;
    const Eigen::Vector3d edge = T_lidar_board * Eigen::Vector3d(radius_m * std::cos(a), radius_m * std::sin(a), 0);
    Eigen::Vector2d truth;
    if (!camera.project(T_camera_lidar * edge, &truth)) continue;
    const Eigen::Vector2d dir = (truth - centre).normalized();
    constexpr double kReach = 3.0;  // beyond blur and anti-aliasing, inside the hole and on the board
    const double inside = bilinear(image, truth - kReach * dir), outside = bilinear(image, truth + kReach * dir);
    const double mid = 0.5 * (inside + outside);
    double prev_s = -kReach, prev = inside - mid, crossing = std::nan("");
    for (double s = -kReach + 0.01; s <= kReach + 1e-9; s += 0.01) {
      const double val = bilinear(image, truth + s * dir) - mid;
      if ((prev < 0) != (val < 0)) {
        crossing = prev_s + (s - prev_s) * prev / (prev - val);
        break;
      }
      prev_s = s;
      prev = val;
    }
    if (std::isnan(crossing)) {
      ADD_FAILURE() << "no edge near the projected hole edge at angle " << k * 4 << " deg";
      continue;
    }
    sum2 += crossing * crossing;
    e.max_px = std::max(e.max_px, std::abs(crossing));
    ++e.count;
  }
  e.rms_px = std::sqrt(sum2 / std::max(1, e.count));
  return e;
}

// A tilted target 4.5 m away, seen by the default rig (both cameras distorted).
Eigen::Isometry3d tilted_target() {
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();
  R.col(1) = Eigen::Vector3d::UnitZ();
  R.col(2) = -Eigen::Vector3d::UnitX();
  R = R * core::rotation_from_rpy(0.3, -0.4, 0.2);
  return core::make_transform(R, Eigen::Vector3d(4.5, 0.25, -0.15));
}

cv::Mat grey(const cv::Mat& radiance) {
  std::vector<cv::Mat> ch;
  cv::split(radiance, ch);
  return ch[1];
}

TEST(CameraSim, RgbHoleEdgesLandOnTheTrueProjectionWithinAThirdOfAPixel) {
  const RigSpec rig;
  const core::TargetSpec target = calibration_target(1, 0.30);
  const Eigen::Isometry3d T_lidar_board = tilted_target();
  const Scene scene = make_calibration_scene(target, T_lidar_board, 1.2, TimeOfDay::kDay);
  const core::PinholeCamera camera(rig.rgb_intrinsics);
  const CameraRenderer renderer(camera);
  RenderOptions render;
  render.supersampling = 8;
  cv::Mat radiance = grey(renderer.render_radiance(scene, rig.T_rgb_lidar.inverse(), render));
  const EdgeErrors e = measure_hole_edges(radiance, camera, rig.T_rgb_lidar, T_lidar_board, target.radius_m);
  EXPECT_EQ(e.count, 90);
  // The bound: true edges land on rendered edges within 0.3 px.
  EXPECT_LT(e.max_px, 0.3);
  EXPECT_LT(e.rms_px, 0.1);
  RecordProperty("rgb_edge_rms_px", std::to_string(e.rms_px));

  // The test can fail: without anti-aliasing, edges snap to pixel centres.
  render.supersampling = 1;
  radiance = grey(renderer.render_radiance(scene, rig.T_rgb_lidar.inverse(), render));
  const EdgeErrors aliased = measure_hole_edges(radiance, camera, rig.T_rgb_lidar, T_lidar_board, target.radius_m);
  EXPECT_GT(aliased.max_px, 0.3);
}

TEST(CameraSim, ThermalHoleEdgesSurviveBlurWithinAThirdOfAPixel) {
  const RigSpec rig;
  const core::TargetSpec target = calibration_target(1, 0.30);
  const Eigen::Isometry3d T_lidar_board = tilted_target();
  const Scene scene = make_calibration_scene(target, T_lidar_board, 1.2, TimeOfDay::kDay);
  const core::PinholeCamera camera(rig.thermal_intrinsics);
  const CameraRenderer renderer(camera);
  ThermalCameraOptions options = rig.thermal;
  options.netd_k = options.fpn_pixel_sigma_k = options.fpn_column_sigma_k = 0.0;
  std::mt19937_64 rng(1);
  cv::Mat counts = renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), options, rng);
  cv::Mat kelvin;
  counts.convertTo(kelvin, CV_32F, options.kelvin_per_count, options.offset_k);
  const EdgeErrors e = measure_hole_edges(kelvin, camera, rig.T_thermal_lidar, T_lidar_board, target.radius_m);
  EXPECT_EQ(e.count, 90);
  // Same bound, after the optics blur (symmetric, so it moves a curved edge by only
  // ~sigma^2 / (2 R) ~ 0.01 px) and the 0.04 K quantisation of the counts.
  EXPECT_LT(e.max_px, 0.3);
}

TEST(CameraSim, ThermalCountsFollowTheLinearRadiometryAndNetd) {
  Scene scene;
  Material wall;
  wall.temperature_k = 300.0;
  wall.emissivity = 1.0;
  scene.add_plane({5, 0, 0}, Eigen::Vector3d::UnitX(), scene.add_material(wall));
  const RigSpec rig;
  const core::PinholeCamera camera(rig.thermal_intrinsics);
  const CameraRenderer renderer(camera);
  ThermalCameraOptions options = rig.thermal;
  options.fpn_pixel_sigma_k = options.fpn_column_sigma_k = 0.0;
  std::mt19937_64 rng(3);
  const cv::Mat counts = renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), options, rng);
  ASSERT_EQ(counts.type(), CV_16UC1);
  cv::Mat kelvin;
  counts.convertTo(kelvin, CV_64F, options.kelvin_per_count, options.offset_k);
  cv::Scalar mean, stddev;
  cv::meanStdDev(kelvin, mean, stddev);
  EXPECT_NEAR(mean[0], 300.0, 0.01);
  // Noise is added after the blur, so the spread is NETD combined with the count
  // quantisation (0.04 K / sqrt(12)); 5 % covers the estimate's own scatter (300k pixels).
  const double expected = std::hypot(options.netd_k, options.kelvin_per_count / std::sqrt(12.0));
  EXPECT_NEAR(stddev[0], expected, 0.05 * expected);
}

TEST(CameraSim, FixedPatternNoiseIsTheSameInEveryFrame) {
  Scene scene;
  Material wall;
  wall.emissivity = 1.0;
  scene.add_plane({5, 0, 0}, Eigen::Vector3d::UnitX(), scene.add_material(wall));
  const RigSpec rig;
  const CameraRenderer renderer{core::PinholeCamera(rig.thermal_intrinsics)};
  ThermalCameraOptions options = rig.thermal;
  options.netd_k = 0.0;
  options.fpn_pixel_sigma_k = 0.2;  // well above the quantisation, so the pattern is visible
  std::mt19937_64 rng(5);
  const cv::Mat a = renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), options, rng);
  const cv::Mat b = renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), options, rng);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(a, mean, stddev);
  EXPECT_GT(stddev[0], 3.0);  // 0.2 K / 0.04 K per count = 5 counts
}

TEST(CameraSim, RgbFramesAreDeterministicForASeed) {
  const RigSpec rig;
  const core::TargetSpec target = calibration_target(1, 0.30);
  const Scene scene = make_calibration_scene(target, tilted_target(), 1.2, TimeOfDay::kDay);
  const CameraRenderer renderer{core::PinholeCamera(rig.rgb_intrinsics)};
  RgbCameraOptions options = rig.rgb;
  options.render.supersampling = 2;
  std::mt19937_64 r1(9), r2(9), r3(10);
  const cv::Mat a = renderer.render_rgb(scene, rig.T_rgb_lidar.inverse(), options, r1);
  const cv::Mat b = renderer.render_rgb(scene, rig.T_rgb_lidar.inverse(), options, r2);
  const cv::Mat c = renderer.render_rgb(scene, rig.T_rgb_lidar.inverse(), options, r3);
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(a.cols, 1288);
  EXPECT_EQ(a.rows, 964);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace rgbdt::sim
