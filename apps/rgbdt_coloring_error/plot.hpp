#pragma once
// Line plots drawn with OpenCV (axes, ticks, labels, legend), for the app's PNG reports.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rgbdt::apps {

struct Curve {
  std::string label;
  std::vector<double> x, y;
  cv::Scalar colour;
  bool dashed = false;
};

struct PlotPanel {
  std::string title, x_label, y_label;
  std::vector<Curve> curves;
};

/// Draws the panels side by side into one image (panel_width x height each).
cv::Mat draw_panels(const std::vector<PlotPanel>& panels, int panel_width = 640, int height = 480);

}  // namespace rgbdt::apps
