#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <random>

#include "rgbdt/core/camera.hpp"

using namespace rgbdt::core;

namespace {

CameraIntrinsics plumb_bob() {
  CameraIntrinsics c;
  c.camera_name = "rgb";
  c.width = 1288;
  c.height = 964;
  c.fx = 1335.054;
  c.fy = 1333.2;
  c.cx = 644.3;
  c.cy = 481.7;
  c.model = DistortionModel::kPlumbBob;
  c.distortion = {-0.21, 0.12, 0.0012, -0.0008, -0.03};
  return c;
}

CameraIntrinsics fisheye() {
  CameraIntrinsics c;
  c.camera_name = "thermal";
  c.width = 640;
  c.height = 512;
  c.fx = 417.20215;
  c.fy = 418.1;
  c.cx = 321.4;
  c.cy = 255.2;
  c.model = DistortionModel::kEquidistant;
  c.distortion = {0.05, -0.02, 0.004, -0.001};
  return c;
}

std::vector<Eigen::Vector3d> sample_points(int n, double max_angle_tan, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-max_angle_tan, max_angle_tan), z(0.5, 30.0);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) {
    const double d = z(rng);
    pts.emplace_back(u(rng) * d, u(rng) * d, d);
  }
  return pts;
}

void expect_jacobian_matches_finite_differences(const PinholeCamera& cam) {
  for (const auto& p : sample_points(200, 0.5, 7)) {
    Eigen::Vector2d uv;
    Eigen::Matrix<double, 2, 3> J;
    ASSERT_TRUE(cam.project(p, &uv, &J));
    for (int k = 0; k < 3; ++k) {
      const double h = 1e-6 * std::max(1.0, std::abs(p[k]));
      Eigen::Vector3d pp = p, pm = p;
      pp[k] += h;
      pm[k] -= h;
      Eigen::Vector2d up, um;
      cam.project(pp, &up);
      cam.project(pm, &um);
      const Eigen::Vector2d fd = (up - um) / (2 * h);
      // Central differences are accurate to ~h^2 * f''' plus rounding ~ eps*|uv|/h.
      EXPECT_NEAR(J(0, k), fd.x(), 1e-5 * std::max(1.0, std::abs(fd.x()))) << "point " << p.transpose();
      EXPECT_NEAR(J(1, k), fd.y(), 1e-5 * std::max(1.0, std::abs(fd.y()))) << "point " << p.transpose();
    }
  }
}

}  // namespace

TEST(PinholeCamera, PlumbBobMatchesOpenCvProjectPoints) {
  const PinholeCamera cam(plumb_bob());
  const auto& c = cam.intrinsics();
  const auto pts = sample_points(500, 0.5, 3);
  std::vector<cv::Point3d> object;
  for (const auto& p : pts) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  std::vector<cv::Point2d> image;
  cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, c.distortion, image);
  for (size_t i = 0; i < pts.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(cam.project(pts[i], &uv));
    EXPECT_NEAR(uv.x(), image[i].x, 1e-9);
    EXPECT_NEAR(uv.y(), image[i].y, 1e-9);
  }
}

TEST(PinholeCamera, EquidistantMatchesOpenCvFisheye) {
  const PinholeCamera cam(fisheye());
  const auto& c = cam.intrinsics();
  const auto pts = sample_points(500, 1.2, 4);
  std::vector<cv::Point3d> object;
  for (const auto& p : pts) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  std::vector<cv::Point2d> image;
  cv::fisheye::projectPoints(object, image, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K,
                             cv::Vec4d(c.distortion[0], c.distortion[1], c.distortion[2], c.distortion[3]));
  for (size_t i = 0; i < pts.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(cam.project(pts[i], &uv));
    EXPECT_NEAR(uv.x(), image[i].x, 1e-8);
    EXPECT_NEAR(uv.y(), image[i].y, 1e-8);
  }
}

TEST(PinholeCamera, PlumbBobJacobianMatchesFiniteDifferences) {
  expect_jacobian_matches_finite_differences(PinholeCamera(plumb_bob()));
}

TEST(PinholeCamera, EquidistantJacobianMatchesFiniteDifferences) {
  expect_jacobian_matches_finite_differences(PinholeCamera(fisheye()));
}

TEST(PinholeCamera, EquidistantJacobianAtOpticalAxis) {
  const PinholeCamera cam(fisheye());
  Eigen::Matrix<double, 2, 3> J;
  Eigen::Vector2d uv;
  ASSERT_TRUE(cam.project({0, 0, 2.0}, &uv, &J));
  EXPECT_NEAR(uv.x(), cam.intrinsics().cx, 1e-12);
  EXPECT_NEAR(J(0, 0), cam.intrinsics().fx / 2.0, 1e-9);
  EXPECT_NEAR(J(1, 1), cam.intrinsics().fy / 2.0, 1e-9);
}

TEST(PinholeCamera, UnprojectInvertsProject) {
  for (const auto& intr : {plumb_bob(), fisheye()}) {
    const PinholeCamera cam(intr);
    for (const auto& p : sample_points(300, 0.45, 5)) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(cam.project(p, &uv));
      const Eigen::Vector3d ray = cam.unproject(uv);
      EXPECT_NEAR(ray.x(), p.x() / p.z(), 1e-10);
      EXPECT_NEAR(ray.y(), p.y() / p.z(), 1e-10);
      EXPECT_DOUBLE_EQ(ray.z(), 1.0);
    }
  }
}

TEST(PinholeCamera, PointsBehindTheCameraDoNotProject) {
  const PinholeCamera cam(plumb_bob());
  Eigen::Vector2d uv(-7, -7);
  EXPECT_FALSE(cam.project({0, 0, -1}, &uv));
  EXPECT_FALSE(cam.project({1, 0, 0}, &uv));
  EXPECT_EQ(uv, Eigen::Vector2d(-7, -7));
}

TEST(PinholeCamera, InImageUsesPixelCentreConvention) {
  const PinholeCamera cam(plumb_bob());
  EXPECT_TRUE(cam.in_image({0, 0}));
  EXPECT_TRUE(cam.in_image({1287.4, 963.4}));
  EXPECT_FALSE(cam.in_image({1287.6, 10}));
  EXPECT_FALSE(cam.in_image({-0.6, 10}));
  EXPECT_FALSE(cam.in_image({5, 5}, 10));
}

TEST(PinholeCamera, RejectsInvalidIntrinsics) {
  CameraIntrinsics c = plumb_bob();
  c.fx = -1;
  EXPECT_THROW(PinholeCamera{c}, std::invalid_argument);
  c = plumb_bob();
  c.width = 0;
  EXPECT_THROW(PinholeCamera{c}, std::invalid_argument);
  c = fisheye();
  c.distortion = {0.1, 0.2, 0.3, 0.4, 0.5};
  EXPECT_THROW(PinholeCamera{c}, std::invalid_argument);
  c = plumb_bob();
  c.distortion = {0, 0, 0, 0, 0, 0.3, 0, 0};
  try {
    PinholeCamera cam(c);
    FAIL() << "rational model accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rational"), std::string::npos) << e.what();
  }
}

TEST(PinholeCamera, ShortPlumbBobVectorIsPaddedWithZeros) {
  CameraIntrinsics c = plumb_bob();
  c.distortion = {-0.2, 0.1, 0, 0};
  const PinholeCamera cam(c);
  EXPECT_EQ(cam.intrinsics().distortion.size(), 5u);
  EXPECT_EQ(cam.intrinsics().distortion[4], 0.0);
}

TEST(PinholeCamera, GenericProjectionAgreesWithClass) {
  const PinholeCamera cam(plumb_bob());
  const auto& c = cam.intrinsics();
  const double k[4] = {c.fx, c.fy, c.cx, c.cy};
  const Eigen::Vector3d p(0.7, -0.4, 3.0);
  double uv[2];
  ASSERT_TRUE(project_generic(c.model, k, c.distortion.data(), p.data(), uv));
  Eigen::Vector2d expected;
  cam.project(p, &expected);
  EXPECT_NEAR(uv[0], expected.x(), 1e-12);
  EXPECT_NEAR(uv[1], expected.y(), 1e-12);
}
