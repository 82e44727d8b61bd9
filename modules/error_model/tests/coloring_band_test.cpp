#include "rgbdt/error_model/coloring_band.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/transform.hpp"
#include "card_scene.hpp"

namespace rgbdt::error_model {
namespace {

using namespace test;  // NOLINT: the scene helpers

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

TEST(ColoringBand, IgnoresTheGroundEvenWhenItOutnumbersTheCard) {
  // rgbdt_sim's setup stands the card on a pavement 1.1 m below the LIDAR: a vertical plane
  // cuts a strip of pavement holding more points than a card at 12 m.
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T_true = true_T_camera_lidar();
  core::Vector6d dv;
  dv << 0.3 * kDeg, 0.25 * kDeg, 0.1 * kDeg, 0.01, 0.0, 0.0;
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T_true;
  Scene scene(12.0);
  scene.card_centre.z() = -0.5;
  scene.ground = true;
  const GrayImage image = render(scene, camera, T_true);
  const auto points = scan(scene, 4);
  const CardBandMeasurement m = measure_card_band(points, sample_point_intensities(points, camera, T_est, image));
  EXPECT_GT(m.ground_points, 200);
  EXPECT_NEAR(m.card_range_m, scene.card_centre.norm(), 0.05);
  const Eigen::Vector3d offset =
      colour_source_offset(scene.card_centre, -Eigen::Vector3d::UnitX(), camera, T_true, camera, T_est);
  const double half_pixel = 0.5 * 12.0 / camera.intrinsics().fx;  // tolerance as above
  EXPECT_NEAR(m.band_x_m, std::abs(offset.dot(scene.card_u)), 0.2 * 12.0 * 0.25 * kDeg + half_pixel);
  EXPECT_NEAR(m.band_y_m, std::abs(offset.dot(scene.card_v)), 0.2 * 12.0 * 0.2 * kDeg + half_pixel);
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
