#include "rgbdt/calib_targets/image_target.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>
#include <random>

#include "rgbdt/core/log.hpp"

namespace ct = rgbdt::calib_targets;

namespace {

struct Scene {
  Eigen::Isometry3d T_camera_board = Eigen::Isometry3d::Identity();  // board z towards camera
  double half = 0.6, radius = 0.3;
  std::vector<Eigen::Vector2d> holes{Eigen::Vector2d::Zero()};
};

rgbdt::core::PinholeCamera make_camera(int w, int h, double f) {
  rgbdt::core::CameraIntrinsics k;
  k.width = w;
  k.height = h;
  k.fx = k.fy = f;
  k.cx = 0.5 * (w - 1);
  k.cy = 0.5 * (h - 1);
  k.model = rgbdt::core::DistortionModel::kNone;
  return rgbdt::core::PinholeCamera(k);
}

Scene scene_at(double z, double x, double y, double yaw, double pitch) {
  Scene s;
  // Board frame: x right, y up, z towards the camera (camera: x right, y down, z forward).
  Eigen::Matrix3d R0;
  R0 << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  s.T_camera_board.linear() = R0 * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                              Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix();
  s.T_camera_board.translation() = Eigen::Vector3d(x, y, z);
  return s;
}

/// Renders board (level `board`) with holes showing the background (`hole`), 4x4
/// supersampled, then Gaussian blur and noise; 8-bit or 16-bit.
cv::Mat render(const Scene& s, const rgbdt::core::PinholeCamera& cam, double board, double hole,
               double blur, double noise, int type, unsigned seed) {
  const auto& k = cam.intrinsics();
  cv::Mat img(k.height, k.width, CV_32F);
  const Eigen::Isometry3d T_board_camera = s.T_camera_board.inverse();
  const Eigen::Vector3d o = T_board_camera.translation();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      double acc = 0.0;
      for (int sv = 0; sv < 4; ++sv) {
        for (int su = 0; su < 4; ++su) {
          const Eigen::Vector3d ray((u - 0.375 + 0.25 * su - k.cx) / k.fx, (v - 0.375 + 0.25 * sv - k.cy) / k.fy, 1.0);
          const Eigen::Vector3d d = T_board_camera.linear() * ray;
          const double t = -o.z() / d.z();
          const Eigen::Vector3d q = o + t * d;
          bool on = t > 0 && std::abs(q.x()) < s.half && std::abs(q.y()) < s.half;
          for (const auto& h : s.holes) {
            if ((q.head<2>() - h).norm() < s.radius) on = false;
          }
          acc += on ? board : hole;
        }
      }
      img.at<float>(v, u) = static_cast<float>(acc / 16.0);
    }
  }
  if (blur > 0) cv::GaussianBlur(img, img, cv::Size(), blur);
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, static_cast<float>(noise));
  for (auto it = img.begin<float>(); it != img.end<float>(); ++it) *it += n(rng);
  cv::Mat out;
  img.convertTo(out, type);
  return out;
}

/// Distances of edge points to the true projected circle of hole k.
std::vector<double> edge_errors(const Scene& s, const rgbdt::core::PinholeCamera& cam, std::size_t k,
                                const std::vector<Eigen::Vector2d>& edges) {
  std::vector<Eigen::Vector2d> curve;
  for (int i = 0; i < 20000; ++i) {
    const double th = 2 * M_PI * i / 20000.0;
    const Eigen::Vector3d p = s.T_camera_board * Eigen::Vector3d(s.holes[k].x() + s.radius * std::cos(th),
                                                                  s.holes[k].y() + s.radius * std::sin(th), 0.0);
    Eigen::Vector2d px;
    cam.project(p, &px);
    curve.push_back(px);
  }
  std::vector<double> err;
  for (const auto& e : edges) {
    double best = 1e9;
    for (const auto& c : curve) best = std::min(best, (c - e).norm());
    err.push_back(best);
  }
  return err;
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

rgbdt::core::TargetSpec paper_target() {
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.3;
  return t;
}

}  // namespace

// The requirement: edge points within 0.5 px of the true edge. Asserted on the 95th
// percentile (single noisy samples may exceed it) and on the mean (systematic bias).
TEST(ImageTarget, RgbAutomaticSubPixelEdges) {
  const auto cam = make_camera(1288, 964, 1335.0);
  const Scene s = scene_at(4.0, 0.3, -0.2, 0.4, 0.2);
  const cv::Mat img = render(s, cam, 200.0, 40.0, 1.0, 2.0, CV_8U, 1u);
  const auto det = ct::detect_target_in_image(img, paper_target(), cam);
  ASSERT_TRUE(det.ok) << det.reason;
  ASSERT_EQ(det.holes.size(), 1u);
  const auto err = edge_errors(s, cam, 0, det.holes[0].edge_points_px);
  EXPECT_GT(err.size(), 100u);
  EXPECT_LT(percentile(err, 0.95), 0.5);
  EXPECT_LT(std::accumulate(err.begin(), err.end(), 0.0) / err.size(), 0.2);
  EXPECT_TRUE(det.holes[0].dark);
  // The Algorithm 1 boundary stops where the blurred ramp (sigma 1 px plus the pixel's own
  // footprint) steps by more than epsilon: inside the true edge by up to ~2 sigma + 1 px.
  std::vector<Eigen::Vector2d> bnd;
  for (const auto& b : det.holes[0].boundary_px) bnd.push_back(b.cast<double>());
  EXPECT_LT(percentile(edge_errors(s, cam, 0, bnd), 0.95), 3.0);
}

TEST(ImageTarget, Thermal16BitBrightHoleWithBlur) {
  const auto cam = make_camera(640, 512, 417.2);
  const Scene s = scene_at(3.0, -0.2, 0.1, -0.3, 0.1);
  // Warm background seen through the hole, 16-bit counts with offset and NETD-like noise.
  const cv::Mat img = render(s, cam, 7400.0, 7900.0, 1.5, 8.0, CV_16U, 2u);
  const auto det = ct::detect_target_in_image(img, paper_target(), cam);
  ASSERT_TRUE(det.ok) << det.reason;
  EXPECT_EQ(det.method, "hole regions");
  EXPECT_FALSE(det.holes[0].dark);
  const auto err = edge_errors(s, cam, 0, det.holes[0].edge_points_px);
  EXPECT_LT(percentile(err, 0.95), 0.5);
}

TEST(ImageTarget, SeededAlgorithm1AndBadInput) {
  const auto cam = make_camera(1288, 964, 1335.0);
  const Scene s = scene_at(4.0, 0.0, 0.0, 0.2, 0.0);
  const cv::Mat img = render(s, cam, 200.0, 40.0, 1.0, 2.0, CV_8U, 3u);
  Eigen::Vector2d centre;
  cam.project(s.T_camera_board.translation(), &centre);
  auto det = ct::detect_target_in_image(img, paper_target(), cam, {}, centre + Eigen::Vector2d(10, 5));
  ASSERT_TRUE(det.ok) << det.reason;
  EXPECT_LT(percentile(edge_errors(s, cam, 0, det.holes[0].edge_points_px), 0.95), 0.5);

  // Seed on the background (outside the board): the region is not a hole.
  det = ct::detect_target_in_image(img, paper_target(), cam, {}, Eigen::Vector2d(20, 20));
  EXPECT_FALSE(det.ok);
  EXPECT_FALSE(det.reason.empty());
  // Wrong size.
  det = ct::detect_target_in_image(cv::Mat(100, 100, CV_8U, cv::Scalar(0)), paper_target(), cam);
  EXPECT_FALSE(det.ok);
  EXPECT_NE(det.reason.find("1288x964"), std::string::npos) << det.reason;
  // No target in view: uniform noise.
  cv::Mat blank(964, 1288, CV_8U);
  cv::randu(blank, 0, 255);
  det = ct::detect_target_in_image(blank, paper_target(), cam);
  EXPECT_FALSE(det.ok);
  EXPECT_FALSE(det.reason.empty());
}

TEST(ImageTarget, FourHoleLayoutOrder) {
  const auto cam = make_camera(1288, 964, 1335.0);
  Scene s = scene_at(3.0, 0.1, 0.0, 0.3, -0.15);
  s.radius = 0.12;
  s.holes = {{-0.3, 0.3}, {0.3, 0.3}, {-0.3, -0.3}, {0.3, -0.3}};
  const cv::Mat img = render(s, cam, 190.0, 30.0, 1.0, 2.0, CV_8U, 4u);
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.12;
  t.holes_m = s.holes;
  const auto det = ct::detect_target_in_image(img, t, cam);
  ASSERT_TRUE(det.ok) << det.reason;
  ASSERT_EQ(det.holes.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    const auto err = edge_errors(s, cam, k, det.holes[k].edge_points_px);
    EXPECT_LT(percentile(err, 0.95), 0.5) << "hole " << k;
  }
}

// A click anywhere on a 4-hole board picks that board: all four holes, the same as the
// automatic detection (same candidates, so the centres agree to well under a pixel); a
// click off the board names the failure.
TEST(ImageTarget, FourHoleBoardPickedBySeed) {
  const auto cam = make_camera(1288, 964, 1335.0);
  Scene s = scene_at(3.0, 0.1, 0.0, 0.3, -0.15);
  s.radius = 0.12;
  s.holes = {{-0.3, 0.3}, {0.3, 0.3}, {-0.3, -0.3}, {0.3, -0.3}};
  const cv::Mat img = render(s, cam, 190.0, 30.0, 1.0, 2.0, CV_8U, 5u);
  rgbdt::core::TargetSpec t;
  t.radius_m = 0.12;
  t.holes_m = s.holes;
  const auto automatic = ct::detect_target_in_image(img, t, cam);
  ASSERT_TRUE(automatic.ok) << automatic.reason;
  // On the board between the lower holes, and near its top-left corner.
  for (const Eigen::Vector3d& on_board : {Eigen::Vector3d(0.0, -0.3, 0.0), Eigen::Vector3d(-0.5, 0.5, 0.0)}) {
    Eigen::Vector2d click;
    ASSERT_TRUE(cam.project(s.T_camera_board * on_board, &click));
    const auto det = ct::detect_target_in_image(img, t, cam, {}, click);
    ASSERT_TRUE(det.ok) << det.reason;
    ASSERT_EQ(det.holes.size(), 4u);
    for (std::size_t k = 0; k < 4; ++k) {
      EXPECT_LT((det.holes[k].center_px - automatic.holes[k].center_px).norm(), 0.1) << "hole " << k;
      EXPECT_LT(percentile(edge_errors(s, cam, k, det.holes[k].edge_points_px), 0.95), 0.5) << "hole " << k;
    }
  }
  // Off the board (well beyond its half size of 0.6 m), in the top-left image corner.
  const auto off = ct::detect_target_in_image(img, t, cam, {}, Eigen::Vector2d(30, 30));
  EXPECT_FALSE(off.ok);
  EXPECT_NE(off.reason.find("seed on the board"), std::string::npos) << off.reason;
}
