#include <gtest/gtest.h>

#include "rgbdt/rgbdt_map/render.hpp"

using namespace rgbdt::rgbdt_map;

namespace {

// A red floor (z = 0, 10 x 10 m) with a hot blue post (x = 5, y = 5) standing on it.
std::vector<MapPoint> floor_and_post() {
  std::vector<MapPoint> points;
  for (double x = 0.0; x < 10.0; x += 0.05) {
    for (double y = 0.0; y < 10.0; y += 0.05) {
      MapPoint p;
      p.position_m = Eigen::Vector3f(x, y, 0.0);
      p.rgb = {220, 20, 20};
      p.has_rgb = true;
      p.temperature_k = 290.0f;
      points.push_back(p);
    }
  }
  for (double z = 0.05; z < 3.0; z += 0.05) {
    for (double x = 4.8; x <= 5.2; x += 0.05) {
      for (double y = 4.8; y <= 5.2; y += 0.05) {
        MapPoint p;
        p.position_m = Eigen::Vector3f(x, y, z);
        p.rgb = {20, 20, 220};
        p.has_rgb = true;
        p.temperature_k = 330.0f;
        points.push_back(p);
      }
    }
  }
  return points;
}

}  // namespace

TEST(Render, TopViewShowsTheHighestSurface) {
  RenderOptions options;
  options.width_px = options.height_px = 200;
  const cv::Mat image = render_top_view(floor_and_post(), RenderMode::kRgb, options);
  ASSERT_EQ(image.type(), CV_8UC3);
  // The post's top hides the floor at the centre; the floor shows elsewhere (BGR).
  EXPECT_EQ(image.at<cv::Vec3b>(100, 100), cv::Vec3b(220, 20, 20));
  EXPECT_EQ(image.at<cv::Vec3b>(50, 50), cv::Vec3b(20, 20, 220));
}

TEST(Render, ThermalPerspectiveHasColourBarAndHotPost) {
  RenderOptions options;
  options.width_px = 320;
  options.height_px = 240;
  const cv::Mat image = render_perspective(floor_and_post(), RenderMode::kThermal, options);
  EXPECT_GT(image.cols, 320);  // colour bar added on the right
  EXPECT_EQ(image.rows, 240);
  // The hot post maps to the top of the scale (bright yellow in inferno), the floor to the
  // bottom (near black): the picture must hold both.
  int hot = 0, cold = 0;
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < 320; ++x) {
      const cv::Vec3b c = image.at<cv::Vec3b>(y, x);
      hot += c[2] > 200 && c[1] > 200;
      cold += c[2] < 30 && c[1] < 30 && c[0] < 30;
    }
  }
  EXPECT_GT(hot, 50);
  EXPECT_GT(cold, 1000);
  EXPECT_THROW(render_perspective({}, RenderMode::kRgb, options), std::invalid_argument);
}
