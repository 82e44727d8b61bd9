#include "rgbdt/error_model/error_propagation.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <random>
#include <stdexcept>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::error_model {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// The paper's rig, roughly: RGB camera of 1288x964 px with mild distortion, LIDAR x forward
/// / z up, camera z forward / y down, a few cm apart, slightly misaligned.
ErrorSources rig_sources() {
  ErrorSources s;
  s.intrinsics.camera_name = "rgb";
  s.intrinsics.width = 1288;
  s.intrinsics.height = 964;
  s.intrinsics.fx = 1335.054;
  s.intrinsics.fy = 1333.2;
  s.intrinsics.cx = 640.5;
  s.intrinsics.cy = 478.9;
  s.intrinsics.model = core::DistortionModel::kPlumbBob;
  s.intrinsics.distortion = {-0.12, 0.08, 0.001, -0.0005, 0.0};
  Eigen::Matrix3d R_camera_lidar;
  R_camera_lidar << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  R_camera_lidar = core::rotation_from_rpy(0.8 * kDeg, -0.5 * kDeg, 1.2 * kDeg) * R_camera_lidar;
  s.T_camera_lidar = core::make_transform(R_camera_lidar, Eigen::Vector3d(0.06, -0.11, 0.03));
  // Calibration-like uncertainties: ~0.2 deg, ~1 cm, with a rotation-translation correlation.
  core::Vector6d sigma;
  sigma << 0.003, 0.004, 0.0025, 0.01, 0.008, 0.015;
  core::Matrix6d correlation = core::Matrix6d::Identity();
  correlation(1, 3) = correlation(3, 1) = 0.6;
  correlation(0, 4) = correlation(4, 0) = -0.4;
  s.extrinsics_covariance = sigma.asDiagonal() * correlation * sigma.asDiagonal();
  // Calibration std devs of fx fy cx cy k1 k2 p1 p2 k3 (OpenCV calibrateCameraExtended-like).
  Eigen::VectorXd k_sigma(9);
  k_sigma << 2.0, 2.0, 1.5, 1.5, 0.004, 0.01, 0.0003, 0.0003, 0.0;
  s.intrinsics_covariance = Eigen::MatrixXd(k_sigma.cwiseAbs2().asDiagonal());
  s.lidar.range_sigma_m = 0.02;
  s.lidar.beam_angle_sigma_rad = 0.05 * kDeg;
  s.lidar.tilt_angle_sigma_rad = 0.1 * kDeg;
  s.rig.T_axis_scanner = core::make_transform(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.0, 0.05));
  return s;
}

/// |a - b| <= 5 % of b, with an absolute floor for components that are ~0 to first order
/// (their Monte Carlo value is then dominated by second-order terms, not comparable).
void expect_within_5_percent(double model, double mc, double floor, const std::string& what) {
  EXPECT_NEAR(model, mc, std::max(0.05 * std::abs(mc), floor)) << what;
}

// 20000 samples: the standard error of a sample standard deviation of a Gaussian is
// sigma / sqrt(2 N) = 0.5 % of sigma, a tenth of the 5 % tolerance; the rest of the
// tolerance is for the (small) non-linearity the first-order model ignores.
constexpr int kSamples = 20000;

TEST(ErrorPropagation, FirstOrderAgreesWithMonteCarloForEverySource) {
  const ColoringErrorModel model(rig_sources());
  const Eigen::Vector3d tilted = Eigen::Vector3d(0.5, -0.2, -1.0).normalized();
  std::uint64_t seed = 7;
  // Near, where LIDAR noise and translation dominate, and far, where rotation does.
  for (double depth : {2.0, 15.0}) {
    for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(640.0, 480.0), Eigen::Vector2d(100.0, 850.0)}) {
      for (const Eigen::Vector3d& normal : {Eigen::Vector3d(-Eigen::Vector3d::UnitZ()), tilted}) {
        const ColoringErrorPrediction fo = model.predict(pixel, depth, normal);
        const ColoringErrorPrediction mc = model.monte_carlo(pixel, depth, normal, kSamples, ++seed);
        EXPECT_EQ(mc.samples, kSamples);
        for (int s = 0; s < kNumSources; ++s) {
          const std::string what = std::string(to_string(static_cast<Source>(s))) + " depth " +
                                   std::to_string(depth) + " pixel " + std::to_string(pixel.x());
          // Floors: 0.005 px and 0.05 mm are far below anything that colours a point wrongly.
          expect_within_5_percent(fo.sources[s].pixel_sigma_u_px(), mc.sources[s].pixel_sigma_u_px(), 0.005, what + " u");
          expect_within_5_percent(fo.sources[s].pixel_sigma_v_px(), mc.sources[s].pixel_sigma_v_px(), 0.005, what + " v");
          expect_within_5_percent(fo.sources[s].surface_sigma_x_m(), mc.sources[s].surface_sigma_x_m(), 5e-5, what + " x");
          expect_within_5_percent(fo.sources[s].surface_sigma_y_m(), mc.sources[s].surface_sigma_y_m(), 5e-5, what + " y");
        }
      }
    }
  }
}

TEST(ErrorPropagation, TotalAgreesWithAnIndependentMonteCarloThroughCoreTypes) {
  // Re-implements the perturbation with core::PinholeCamera, core::from_vector6 and
  // core::TiltRig only, so a shared bug in the library's own sampler cannot hide.
  const ErrorSources s = rig_sources();
  const ColoringErrorModel model(s);
  const Eigen::Vector2d pixel(900.0, 300.0);
  const double depth = 7.5;
  const ColoringErrorPrediction fo = model.predict(pixel, depth);

  // The beam that hits the point: tilt, range and angle from the geometry (mount offset along z).
  const Eigen::Vector3d p = fo.point_lidar;
  const double tz = 0.05;
  // Ry(-phi) p has z = tz: p.x sin(phi) + p.z cos(phi) = tz.
  const double radius = std::hypot(p.x(), p.z());
  const double phi = std::atan2(p.x(), p.z()) - std::acos(tz / radius);
  const Eigen::Vector3d q = s.rig.T_lidar_scanner(phi).inverse() * p;
  ASSERT_NEAR(q.z(), 0.0, 1e-9);
  const double range = std::hypot(q.x(), q.y()), theta = std::atan2(q.y(), q.x());

  std::mt19937_64 rng(42);
  std::normal_distribution<double> n01;
  Eigen::LLT<core::Matrix6d> llt(s.extrinsics_covariance);
  const core::Vector6d v0 = core::to_vector6(s.T_camera_lidar);
  double sum_u = 0, sum_v = 0, sum_uu = 0, sum_vv = 0;
  for (int i = 0; i < kSamples; ++i) {
    core::CameraIntrinsics k = s.intrinsics;
    const Eigen::VectorXd k_sigma = s.intrinsics_covariance.diagonal().cwiseSqrt();
    k.fx += k_sigma[0] * n01(rng);
    k.fy += k_sigma[1] * n01(rng);
    k.cx += k_sigma[2] * n01(rng);
    k.cy += k_sigma[3] * n01(rng);
    for (int j = 0; j < 5; ++j) k.distortion[j] += k_sigma[4 + j] * n01(rng);
    core::Vector6d z;
    for (int j = 0; j < 6; ++j) z[j] = n01(rng);
    const Eigen::Isometry3d T = core::from_vector6(v0 + llt.matrixL() * z);
    const double r = range + s.lidar.range_sigma_m * n01(rng);
    const double a = theta + s.lidar.beam_angle_sigma_rad * n01(rng);
    const double t = phi + s.lidar.tilt_angle_sigma_rad * n01(rng);
    const Eigen::Vector3d p_noisy = s.rig.T_lidar_scanner(t) * Eigen::Vector3d(r * std::cos(a), r * std::sin(a), 0.0);
    Eigen::Vector2d uv;
    ASSERT_TRUE(core::PinholeCamera(k).project(T * p_noisy, &uv));
    const Eigen::Vector2d e = uv - fo.pixel;
    sum_u += e.x();
    sum_v += e.y();
    sum_uu += e.x() * e.x();
    sum_vv += e.y() * e.y();
  }
  const double sigma_u = std::sqrt(sum_uu / kSamples - std::pow(sum_u / kSamples, 2));
  const double sigma_v = std::sqrt(sum_vv / kSamples - std::pow(sum_v / kSamples, 2));
  const SourceError& total = fo[Source::kTotal];
  EXPECT_NEAR(total.pixel_sigma_u_px(), sigma_u, 0.05 * sigma_u);
  EXPECT_NEAR(total.pixel_sigma_v_px(), sigma_v, 0.05 * sigma_v);
  EXPECT_GT(sigma_u, 1.0);  // the case is not trivially small
}

TEST(ErrorPropagation, RotationErrorGrowsWithDepthOnTheSurfaceTranslationErrorDoesNot) {
  // The paper's conclusion (Sec. 4.3.3) in metric terms, with exact values: for a camera
  // rotation error sigma about its y axis the band on a fronto-parallel surface at the image
  // centre is Z sigma wide; a camera translation error sigma along x gives sigma at any depth.
  ErrorSources s = rig_sources();
  s.intrinsics.distortion = {0, 0, 0, 0, 0};
  s.intrinsics_covariance.resize(0, 0);
  s.lidar = LidarNoise{0.0, 0.0, 0.0};
  s.extrinsics_perturbation = ExtrinsicsPerturbation::kLeft;
  s.extrinsics_covariance.setZero();
  s.extrinsics_covariance(1, 1) = std::pow(0.002, 2);
  s.extrinsics_covariance(3, 3) = std::pow(0.01, 2);
  const ColoringErrorModel model(s);
  const Eigen::Vector2d centre(s.intrinsics.cx, s.intrinsics.cy);
  for (double depth : {1.0, 5.0, 15.0}) {
    const ColoringErrorPrediction p = model.predict(centre, depth);
    // Exact first-order identities; 1e-9 relative is floating-point rounding.
    EXPECT_NEAR(p[Source::kRotation].pixel_sigma_u_px(), s.intrinsics.fx * 0.002, 1e-9 * s.intrinsics.fx);
    EXPECT_NEAR(p[Source::kRotation].surface_sigma_x_m(), depth * 0.002, 1e-9 * depth);
    EXPECT_NEAR(p[Source::kTranslation].pixel_sigma_u_px(), s.intrinsics.fx * 0.01 / depth, 1e-9 * s.intrinsics.fx);
    EXPECT_NEAR(p[Source::kTranslation].surface_sigma_x_m(), 0.01, 1e-11);
    EXPECT_NEAR(p[Source::kLidar].pixel_rms_px(), 0.0, 1e-12);
    EXPECT_NEAR(p[Source::kTotal].surface_sigma_x_m(), std::hypot(depth * 0.002, 0.01), 1e-9);
  }
}

TEST(ErrorPropagation, LidarNoiseMovesThePixelOnlyThroughTheBaseline) {
  // With camera and LIDAR at the same origin, range noise runs along the camera ray.
  ErrorSources s = rig_sources();
  s.T_camera_lidar = core::make_transform(s.T_camera_lidar.linear(), Eigen::Vector3d::Zero());
  s.rig.T_axis_scanner = Eigen::Isometry3d::Identity();
  s.lidar = LidarNoise{0.03, 0.0, 0.0};
  const ColoringErrorModel model(s);
  EXPECT_NEAR(model.predict(Eigen::Vector2d(300, 700), 6.0)[Source::kLidar].pixel_rms_px(), 0.0, 1e-9);
  // ... and with a baseline, range noise moves the pixel by parallax, which falls off with
  // depth (Eq. (7)). (Beam and tilt angle noise would not: they move it by fx sigma.)
  ErrorSources b = rig_sources();
  b.lidar = LidarNoise{0.03, 0.0, 0.0};
  const ColoringErrorModel with_baseline(b);
  const double near = with_baseline.predict(Eigen::Vector2d(640, 480), 5.0)[Source::kLidar].pixel_rms_px();
  const double far = with_baseline.predict(Eigen::Vector2d(640, 480), 10.0)[Source::kLidar].pixel_rms_px();
  EXPECT_GT(near, 0.1);
  EXPECT_LT(far, 0.5 * near);
}

TEST(ErrorPropagation, LidarPointCovarianceHasTheRangeSigmaAlongTheBeam) {
  ErrorSources s = rig_sources();
  s.lidar = LidarNoise{0.02, 0.0, 0.0};
  const ColoringErrorModel model(s);
  const Eigen::Vector3d p(8.0, 1.0, -0.7);
  // The scanner origin is Ry(phi) (0, 0, 0.05) at the tilt phi whose scan plane holds p.
  const double phi = std::atan2(p.x(), p.z()) - std::acos(0.05 / std::hypot(p.x(), p.z()));
  const Eigen::Vector3d origin = s.rig.T_lidar_scanner(phi).translation();
  const Eigen::Vector3d beam = (p - origin).normalized();
  const Eigen::Matrix3d expected = 0.0004 * beam * beam.transpose();
  // Same closed form computed two ways: rounding only.
  EXPECT_LT((model.lidar_point_covariance(p) - expected).cwiseAbs().maxCoeff(), 1e-12)
      << model.lidar_point_covariance(p) << "\n" << expected;
}

TEST(ErrorPropagation, ValidateNamesTheProblem) {
  ErrorSources s = rig_sources();
  s.intrinsics_covariance = Eigen::MatrixXd::Identity(6, 6);
  EXPECT_NE(s.validate().find("intrinsics_covariance is 6x6"), std::string::npos) << s.validate();
  EXPECT_THROW(ColoringErrorModel{s}, std::invalid_argument);
  s = rig_sources();
  s.extrinsics_covariance(0, 0) = -1.0;
  EXPECT_NE(s.validate().find("positive semi-definite"), std::string::npos) << s.validate();
  s = rig_sources();
  s.lidar.range_sigma_m = -0.1;
  EXPECT_NE(s.validate().find("range_sigma_m"), std::string::npos) << s.validate();
  const ColoringErrorModel model(rig_sources());
  EXPECT_THROW(model.predict(Eigen::Vector2d(1, 1), -2.0), std::invalid_argument);
  EXPECT_THROW(model.predict(Eigen::Vector2d(640, 480), 5.0, Eigen::Vector3d::UnitX()), std::invalid_argument);
  EXPECT_THROW(model.monte_carlo(Eigen::Vector2d(640, 480), 5.0, -Eigen::Vector3d::UnitZ(), 1), std::invalid_argument);
}

TEST(ErrorPropagation, AcrossEdgeSigmaPicksThePerpendicularComponent) {
  Eigen::Matrix2d C;
  C << 4.0, 0.0, 0.0, 9.0;
  EXPECT_DOUBLE_EQ(across_edge_sigma_m(C, Eigen::Vector2d(0, 1)), 2.0);  // vertical edge: x error
  EXPECT_DOUBLE_EQ(across_edge_sigma_m(C, Eigen::Vector2d(1, 0)), 3.0);  // horizontal edge: y error
}

}  // namespace
}  // namespace rgbdt::error_model
