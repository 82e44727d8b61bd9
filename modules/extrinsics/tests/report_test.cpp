#include "rgbdt/extrinsics/report.hpp"

#include <gtest/gtest.h>

#include <random>

#include "synthetic_views.hpp"

namespace rgbdt::extrinsics {
namespace {

TEST(Report, CameraToCameraComposesAndPropagatesTheCovariance) {
  const Eigen::Isometry3d T_a = testing::true_T_camera_lidar();
  const Eigen::Isometry3d T_b =
      core::make_transform(core::rotation_from_rpy(0.1, -0.05, 0.02), Eigen::Vector3d(0.2, 0.0, -0.05)) * T_a;
  core::Matrix6d cov_a = core::Matrix6d::Zero(), cov_b = core::Matrix6d::Zero();
  cov_a.diagonal() << 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6;
  cov_b.diagonal() << 4e-6, 4e-6, 4e-6, 4e-6, 4e-6, 4e-6;
  const CameraToCamera c = camera_to_camera(T_a, cov_a, T_b, cov_b);
  EXPECT_LT(core::rotation_error_rad(c.T_b_a, T_b * T_a.inverse()), 1e-12);
  EXPECT_LT(core::translation_error_m(c.T_b_a, T_b * T_a.inverse()), 1e-12);
  // Monte Carlo of the same map: the first-order covariance must match the sample one
  // within the sampling error (4000 samples: ~5% on variances; 15% allowed).
  std::mt19937 rng(1);
  std::normal_distribution<double> n01;
  const core::Vector6d mean = core::to_vector6(c.T_b_a);
  core::Matrix6d sample = core::Matrix6d::Zero();
  const int N = 4000;
  for (int i = 0; i < N; ++i) {
    core::Vector6d da, db;
    for (int k = 0; k < 6; ++k) {
      da[k] = n01(rng) * std::sqrt(cov_a(k, k));
      db[k] = n01(rng) * std::sqrt(cov_b(k, k));
    }
    const Eigen::Isometry3d Ta = core::from_vector6(core::to_vector6(T_a) + da);
    const Eigen::Isometry3d Tb = core::from_vector6(core::to_vector6(T_b) + db);
    const core::Vector6d d = core::to_vector6(Tb * Ta.inverse()) - mean;
    sample += d * d.transpose() / N;
  }
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(c.covariance(k, k), sample(k, k), 0.15 * sample(k, k)) << k;
}

TEST(Report, OverlayAndMarkdownShowTheViewsAndTheErrors) {
  const core::PinholeCamera camera(testing::table1_intrinsics());
  const Eigen::Isometry3d truth = testing::true_T_camera_lidar();
  auto views = testing::make_views(camera, truth, testing::table1_placements());
  const EdgeAlignmentResult r = align_edges(views, camera);
  const cv::Mat grey(camera.height(), camera.width(), CV_16U, cv::Scalar(3000));
  const cv::Mat overlay = draw_overlay(grey, views[0], camera, r.T_camera_lidar_initial, r.T_camera_lidar);
  EXPECT_EQ(overlay.type(), CV_8UC3);
  EXPECT_EQ(overlay.cols, camera.width());
  const std::string md = format_alignment_report("rgb", r, truth);
  EXPECT_NE(md.find("## rgb"), std::string::npos);
  EXPECT_NE(md.find("| view 7 |"), std::string::npos) << md;
  EXPECT_NE(md.find("error vs ground truth"), std::string::npos) << md;
  EXPECT_THROW(to_display_bgr(cv::Mat(4, 4, CV_32F)), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::extrinsics
