#include "rgbdt/error_model/coloring_band.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::error_model {
namespace {

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
  /// Colour seen along the ray origin + s dir (first hit), or nothing (false).
  bool cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, Eigen::Vector3d* hit, float* colour) const {
    if (dir.x() <= 0.0) return false;
    const double s_card = (depth_m - origin.x()) / dir.x();
    const Eigen::Vector3d c = origin + s_card * dir;
    const Eigen::Vector3d d = c - card_centre;
    if (std::abs(d.dot(card_u)) <= half_w && std::abs(d.dot(card_v)) <= half_h) {
      *hit = c;
      *colour = card_colour;
      return true;
    }
    const double s_cloth = (depth_m + gap_m - origin.x()) / dir.x();
    const Eigen::Vector3d b = origin + s_cloth * dir;
    if (std::abs(b.y() - card_centre.y()) > 2.5 || std::abs(b.z() - card_centre.z()) > 2.0) return false;
    *hit = b;
    *colour = cloth_colour;
    return true;
  }
};

core::PinholeCamera rgb_camera() {
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

Eigen::Isometry3d true_T_camera_lidar() {
  Eigen::Matrix3d R;
  R << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  // A small lateral baseline keeps the cloth's occlusion shadow behind the card edges
  // (baseline * gap / depth = 1.2 mm at 5 m) well below what is measured here.
  return core::make_transform(R, Eigen::Vector3d(0.02, -0.01, 0.05));
}

GrayImage render(const Scene& scene, const core::PinholeCamera& camera, const Eigen::Isometry3d& T_camera_lidar) {
  GrayImage image{camera.width(), camera.height(), {}};
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, 0.0f);
  const Eigen::Isometry3d T_lidar_camera = T_camera_lidar.inverse();
  // Pixel rays (Newton undistortion) are the slow part; every scene uses the same camera.
  static std::vector<Eigen::Vector3d> rays;
  if (rays.empty()) {
    for (int v = 0; v < image.height; ++v) {
      for (int u = 0; u < image.width; ++u) rays.push_back(camera.unproject(Eigen::Vector2d(u, v)));
    }
  }
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const Eigen::Vector3d dir = T_lidar_camera.linear() * rays[static_cast<std::size_t>(v) * image.width + u];
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
std::vector<Eigen::Vector3d> scan(const Scene& scene, unsigned seed, bool mixed_pixels = false) {
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
      float colour;
      if (!scene.cast(Eigen::Vector3d::Zero(), dir, &hit, &colour)) continue;
      if (mixed_pixels) {
        const double next = yaw + 0.25 * kDeg;
        const Eigen::Vector3d dir2(std::cos(pitch) * std::cos(next), std::cos(pitch) * std::sin(next), std::sin(pitch));
        Eigen::Vector3d hit2;
        float colour2;
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

TEST(ColoringBand, PerfectCalibrationLeavesAlmostNoBand) {
  const Scene scene(7.5);
  const core::PinholeCamera camera = rgb_camera();
  const GrayImage image = render(scene, camera, true_T_camera_lidar());
  const auto points = scan(scene, 3);
  const auto colours = sample_point_intensities(points, camera, true_T_camera_lidar(), image);
  const CardBandMeasurement m = measure_card_band(points, colours);
  EXPECT_NEAR(m.card_size_m.x(), 1.2, 0.15);  // roll and 3.3 cm spacing blur the extent
  EXPECT_NEAR(m.card_size_m.y(), 0.9, 0.15);
  EXPECT_NEAR(m.card_range_m, scene.card_centre.norm(), 0.05);
  // Nearest-pixel sampling is exact up to half a pixel (0.3 cm at 7.5 m) plus the occlusion
  // shadow (0.1 cm): under 1 cm.
  EXPECT_LT(m.band_x_m, 0.01);
  EXPECT_LT(m.band_y_m, 0.01);
}

TEST(ColoringBand, MeasuredBandMatchesTheColourOffsetOfAWrongExtrinsic) {
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T_true = true_T_camera_lidar();
  // An estimate off by 0.25 deg about camera y, 0.3 deg about camera x, 1 cm in x.
  core::Vector6d dv;
  dv << 0.3 * kDeg, 0.25 * kDeg, 0.1 * kDeg, 0.01, 0.0, 0.0;
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T_true;
  for (double depth : {5.0, 10.0, 15.0}) {
    const Scene scene(depth);
    const GrayImage image = render(scene, camera, T_true);
    const auto points = scan(scene, 11);
    const auto colours = sample_point_intensities(points, camera, T_est, image);
    const CardBandMeasurement m = measure_card_band(points, colours);
    const Eigen::Vector3d offset =
        colour_source_offset(scene.card_centre, -Eigen::Vector3d::UnitX(), camera, T_true, camera, T_est);
    const double expected_x = std::abs(offset.dot(scene.card_u)), expected_y = std::abs(offset.dot(scene.card_v));
    // Tolerance: the count estimator's spread is about half the point spacing divided by the
    // square root of the number of scan lines / beams along an edge (>= 8 at 15 m), i.e.
    // < 0.2 spacing; plus half a pixel of nearest-pixel sampling. Spacing: 0.25 deg in x,
    // 0.2 deg in y.
    const double spacing_x = depth * 0.25 * kDeg, spacing_y = depth * 0.2 * kDeg;
    const double half_pixel = 0.5 * depth / camera.intrinsics().fx;
    EXPECT_NEAR(m.band_x_m, expected_x, 0.2 * spacing_x + half_pixel) << "depth " << depth;
    EXPECT_NEAR(m.band_y_m, expected_y, 0.2 * spacing_y + half_pixel) << "depth " << depth;
    EXPECT_GT(expected_x, 0.02);  // the case is not trivially small
  }
}

TEST(ColoringBand, IgnoresMixedPixelsBetweenCardAndCloth) {
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T_true = true_T_camera_lidar();
  core::Vector6d dv;
  dv << 0.3 * kDeg, 0.25 * kDeg, 0.1 * kDeg, 0.01, 0.0, 0.0;
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T_true;
  Scene scene(10.0);
  scene.gap_m = 1.2;  // as in rgbdt_sim's setups
  const GrayImage image = render(scene, camera, T_true);
  const auto points = scan(scene, 9, /*mixed_pixels=*/true);
  const CardBandMeasurement m = measure_card_band(points, sample_point_intensities(points, camera, T_est, image));
  EXPECT_GT(m.mixed_points, 20);
  const Eigen::Vector3d offset =
      colour_source_offset(scene.card_centre, -Eigen::Vector3d::UnitX(), camera, T_true, camera, T_est);
  // Tolerance as above; a mixed pixel that were counted would add a whole beam spacing.
  const double half_pixel = 0.5 * 10.0 / camera.intrinsics().fx;
  EXPECT_NEAR(m.band_x_m, std::abs(offset.dot(scene.card_u)), 0.2 * 10.0 * 0.25 * kDeg + half_pixel);
  EXPECT_NEAR(m.band_y_m, std::abs(offset.dot(scene.card_v)), 0.2 * 10.0 * 0.2 * kDeg + half_pixel);
}

TEST(ColoringBand, FindsACardThatIsDarkerThanTheCloth) {
  // In a thermal image the card may be colder than the cloth: same geometry, colours swapped.
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T_true = true_T_camera_lidar();
  core::Vector6d dv;
  dv << -0.2 * kDeg, 0.3 * kDeg, 0.0, 0.0, 0.01, 0.0;
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T_true;
  Scene scene(7.5);
  scene.card_colour = 60.0f;
  scene.cloth_colour = 180.0f;
  const GrayImage image = render(scene, camera, T_true);
  const auto points = scan(scene, 5);
  const CardBandMeasurement m = measure_card_band(points, sample_point_intensities(points, camera, T_est, image));
  EXPECT_FALSE(m.card_is_bright);
  EXPECT_NEAR(m.card_range_m, scene.card_centre.norm(), 0.05);
  const Eigen::Vector3d offset =
      colour_source_offset(scene.card_centre, -Eigen::Vector3d::UnitX(), camera, T_true, camera, T_est);
  // Same tolerance as above: 0.2 point spacing + half a pixel.
  const double half_pixel = 0.5 * 7.5 / camera.intrinsics().fx;
  EXPECT_NEAR(m.band_x_m, std::abs(offset.dot(scene.card_u)), 0.2 * 7.5 * 0.25 * kDeg + half_pixel);
  EXPECT_NEAR(m.band_y_m, std::abs(offset.dot(scene.card_v)), 0.2 * 7.5 * 0.2 * kDeg + half_pixel);
}

TEST(ColoringBand, ColourSourceOffsetIsZeroForTheTrueCalibrationAndGrowsWithRotationError) {
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T = true_T_camera_lidar();
  const Eigen::Vector3d p(6.0, 0.3, -0.2);
  EXPECT_LT(colour_source_offset(p, -Eigen::Vector3d::UnitX(), camera, T, camera, T).norm(), 1e-9);
  core::Vector6d dv = core::Vector6d::Zero();
  dv[1] = 0.001;  // 1 mrad about camera y: the colour comes from ~ depth * 1 mm/m away
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T;
  const double near = colour_source_offset(Eigen::Vector3d(5, 0, 0), -Eigen::Vector3d::UnitX(), camera, T, camera, T_est).norm();
  const double far = colour_source_offset(Eigen::Vector3d(15, 0, 0), -Eigen::Vector3d::UnitX(), camera, T, camera, T_est).norm();
  EXPECT_NEAR(near, 5.0 * 0.001, 2e-4);  // first order in the angle; 4 % slack for the 5 cm offset of the camera
  EXPECT_NEAR(far, 15.0 * 0.001, 4e-4);
}

TEST(ColoringBand, RejectsBadInputWithTheReason) {
  const core::PinholeCamera camera = rgb_camera();
  GrayImage small{10, 10, std::vector<float>(100, 0.0f)};
  EXPECT_THROW(sample_point_intensities({}, camera, true_T_camera_lidar(), small), std::invalid_argument);
  EXPECT_THROW(measure_card_band({Eigen::Vector3d(1, 0, 0)}, {}), std::invalid_argument);
  try {
    measure_card_band(std::vector<Eigen::Vector3d>(50, Eigen::Vector3d(5, 0, 0)), std::vector<double>(50, 10.0));
    FAIL() << "no exception";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected a card before a cloth"), std::string::npos) << e.what();
  }
  CardBandOptions bad;
  bad.edge_strip_m = -1.0;
  EXPECT_NE(bad.validate().find("edge_strip_m"), std::string::npos);
}

}  // namespace
}  // namespace rgbdt::error_model
