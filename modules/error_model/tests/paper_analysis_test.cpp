#include "rgbdt/error_model/paper_analysis.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::error_model {
namespace {

constexpr double kRgbFx = 1335.054;     // paper Sec. 4.3.1, colour camera
constexpr double kThermalFx = 417.20215;  // paper Sec. 4.3.1, thermal camera
// The paper prints six decimals; 1e-6 m is the rounding of its last digit.
constexpr double kPaperDigitsM = 1e-6;

core::PinholeCamera pinhole(double fx) {
  core::CameraIntrinsics k;
  k.width = 1288;
  k.height = 964;
  k.fx = fx;
  k.fy = fx * 1.01;
  k.cx = 644.3;
  k.cy = 481.7;
  k.model = core::DistortionModel::kNone;
  return core::PinholeCamera(k);
}

TEST(PaperAnalysis, Eq9ReproducesThePapersLidarNoiseDepths) {
  EXPECT_NEAR(lidar_noise_depth_m(kRgbFx, 0.02, 5.0), 4.303249, kPaperDigitsM);
  EXPECT_NEAR(lidar_noise_depth_m(kThermalFx, 0.02, 5.0), 3.512751, kPaperDigitsM);
}

TEST(PaperAnalysis, Eq9RootMakesTheOnePixelErrorOfEq8) {
  // At the root, |(fx X - fx Z) dz| / (Z^2 + Z dz) = 1 (Eq. (8)), to rounding.
  const double z = lidar_noise_depth_m(kRgbFx, 0.02, 5.0);
  const double error_px = std::abs((kRgbFx * 5.0 - kRgbFx * z) * 0.02) / (z * z + z * 0.02);
  EXPECT_NEAR(error_px, 1.0, 1e-9);
}

TEST(PaperAnalysis, IntrinsicsDepthReproducesThePapersEq14Numbers) {
  EXPECT_NEAR(intrinsics_depth_m(kRgbFx, 2.0, 0.02, 5.0), 4.304037, kPaperDigitsM);
  EXPECT_NEAR(intrinsics_depth_m(kThermalFx, 6.0, 0.02, 5.0), 3.524249, kPaperDigitsM);
}

TEST(PaperAnalysis, PrintedEq14DoesNotGiveThePapersNumbers) {
  // The numbers the header documents for the printed equation (computed independently:
  // b = fx dz + dfx X + dz, c = -(dz fx X + dz dfx X), root = (-b + sqrt(b^2 - 4c)) / 2).
  EXPECT_NEAR(printed_eq14_depth_m(kRgbFx, 2.0, 0.02, 5.0), 3.337728, kPaperDigitsM);
  EXPECT_NEAR(printed_eq14_depth_m(kThermalFx, 6.0, 0.02, 5.0), 1.073105, kPaperDigitsM);
  EXPECT_GT(std::abs(printed_eq14_depth_m(kRgbFx, 2.0, 0.02, 5.0) - 4.304037), 0.5);
}

TEST(PaperAnalysis, Eq19MatchesDirectProjectionWithARotationAboutTheOpticalAxis) {
  const core::PinholeCamera camera = pinhole(kRgbFx);
  for (double z : {2.0, 5.0, 7.5, 10.0, 15.0}) {
    for (double dtheta : {-0.01, 0.002, 0.0175}) {
      const Eigen::Vector3d p(0.4 * z / 5.0 + 0.3, -0.25, z);
      Eigen::Vector2d uv_true, uv_rotated;
      ASSERT_TRUE(camera.project(p, &uv_true));
      ASSERT_TRUE(camera.project(Eigen::AngleAxisd(dtheta, Eigen::Vector3d::UnitZ()) * p, &uv_rotated));
      // Both are exact pinhole projections; only floating-point rounding separates them.
      EXPECT_NEAR(rotation_pixel_error_px(kRgbFx, p.x(), p.y(), p.z(), dtheta),
                  uv_rotated.x() - uv_true.x(), 1e-9)
          << "z = " << z << " dtheta = " << dtheta;
    }
  }
}

TEST(PaperAnalysis, Eq25MatchesDirectProjectionWithATranslationError) {
  const core::PinholeCamera camera = pinhole(kThermalFx);
  const Eigen::Vector3d t(0.1, -0.05, 0.08);  // LIDAR to camera offset [m]
  for (double z : {1.0, 5.0, 10.0, 15.0}) {
    const Eigen::Vector3d p(0.7, 0.2, z);
    Eigen::Vector2d uv_true, uv_shifted;
    ASSERT_TRUE(camera.project(p + t, &uv_true));
    ASSERT_TRUE(camera.project(p + t + Eigen::Vector3d(0.03, 0.0, 0.0), &uv_shifted));
    // Exact when dtz = 0 (Eq. (24) is then no approximation): rounding only.
    EXPECT_NEAR(translation_pixel_error_px(kThermalFx, z, t.z(), 0.03), uv_shifted.x() - uv_true.x(), 1e-9);
  }
}

TEST(PaperAnalysis, Eq25ApproximationImprovesWithDepthWhenTzIsAlsoWrong) {
  // Eq. (24) drops dtz; its relative error must shrink as Z grows, as the paper argues.
  const core::PinholeCamera camera = pinhole(kRgbFx);
  const Eigen::Vector3d t(0.1, 0.0, 0.05), dt(0.02, 0.0, 0.05);
  double previous = 1e9;
  for (double z : {2.0, 5.0, 10.0, 20.0}) {
    const Eigen::Vector3d p(0.5, 0.0, z);
    Eigen::Vector2d a, b;
    ASSERT_TRUE(camera.project(p + t, &a));
    ASSERT_TRUE(camera.project(p + t + dt, &b));
    const double deviation = std::abs(translation_pixel_error_px(kRgbFx, z, t.z(), dt.x()) - (b.x() - a.x()));
    EXPECT_LT(deviation, previous);
    previous = deviation;
  }
}

TEST(PaperAnalysis, RejectsNonPositiveInputsWithTheirName) {
  try {
    lidar_noise_depth_m(-1.0, 0.02);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fx_px"), std::string::npos) << e.what();
  }
  EXPECT_THROW(lidar_noise_depth_m(1000.0, 0.0), std::invalid_argument);
  EXPECT_THROW(intrinsics_depth_m(10.0, -20.0, 0.02), std::invalid_argument);
  EXPECT_THROW(rotation_pixel_error_px(1000.0, 1.0, 1.0, 0.0, 0.01), std::invalid_argument);
  EXPECT_THROW(translation_pixel_error_px(1000.0, 1.0, -2.0, 0.01), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::error_model
