#include "plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace rgbdt::apps {
namespace {

/// "Nice" tick step (1, 2 or 5 times a power of ten) giving about `count` ticks.
double nice_step(double range, int count) {
  const double raw = range / std::max(count, 1);
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * power >= raw) return m * power;
  }
  return 10.0 * power;
}

std::string format_tick(double v, double step) {
  char buf[32];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

void draw_panel(cv::Mat& canvas, const cv::Rect& area, const PlotPanel& panel) {
  const int left = 70, right = 15, top = 40, bottom = 55;
  const cv::Rect plot(area.x + left, area.y + top, area.width - left - right, area.height - top - bottom);
  double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min, y_max = 0.0;
  for (const auto& c : panel.curves) {
    for (std::size_t i = 0; i < c.x.size(); ++i) {
      x_min = std::min(x_min, c.x[i]);
      x_max = std::max(x_max, c.x[i]);
      if (std::isfinite(c.y[i])) y_max = std::max(y_max, c.y[i]);
    }
  }
  if (!(x_max > x_min)) x_max = x_min + 1.0;
  if (!(y_max > 0.0)) y_max = 1.0;
  const double y_step = nice_step(y_max, 6);
  y_max = std::ceil(y_max / y_step) * y_step;
  const double x_step = nice_step(x_max - x_min, 8);
  auto to_px = [&](double x, double y) {
    return cv::Point(plot.x + static_cast<int>(std::lround((x - x_min) / (x_max - x_min) * plot.width)),
                     plot.y + plot.height - static_cast<int>(std::lround(y / y_max * plot.height)));
  };
  const cv::Scalar black(0, 0, 0), grey(215, 215, 215);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  // Grid and ticks.
  for (double y = 0.0; y <= y_max + 1e-9 * y_max; y += y_step) {
    const cv::Point p = to_px(x_min, y);
    cv::line(canvas, p, cv::Point(plot.x + plot.width, p.y), grey, 1);
    cv::line(canvas, p, cv::Point(p.x - 5, p.y), black, 1);
    const std::string label = format_tick(y, y_step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, font, 0.42, 1, &base);
    cv::putText(canvas, label, cv::Point(p.x - 8 - size.width, p.y + size.height / 2), font, 0.42, black, 1, cv::LINE_AA);
  }
  for (double x = std::ceil(x_min / x_step) * x_step; x <= x_max + 1e-9; x += x_step) {
    const cv::Point p = to_px(x, 0.0);
    cv::line(canvas, p, cv::Point(p.x, plot.y), grey, 1);
    cv::line(canvas, p, cv::Point(p.x, p.y + 5), black, 1);
    const std::string label = format_tick(x, x_step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, font, 0.42, 1, &base);
    cv::putText(canvas, label, cv::Point(p.x - size.width / 2, p.y + 20), font, 0.42, black, 1, cv::LINE_AA);
  }
  cv::rectangle(canvas, plot, black, 1);
  // Curves.
  for (const auto& c : panel.curves) {
    for (std::size_t i = 1; i < c.x.size(); ++i) {
      if (!std::isfinite(c.y[i - 1]) || !std::isfinite(c.y[i])) continue;
      if (c.dashed && i % 2 == 0) continue;
      cv::line(canvas, to_px(c.x[i - 1], c.y[i - 1]), to_px(c.x[i], c.y[i]), c.colour, 2, cv::LINE_AA);
    }
  }
  // Labels and title.
  int base = 0;
  cv::Size size = cv::getTextSize(panel.x_label, font, 0.5, 1, &base);
  cv::putText(canvas, panel.x_label, cv::Point(plot.x + (plot.width - size.width) / 2, area.y + area.height - 12), font,
              0.5, black, 1, cv::LINE_AA);
  size = cv::getTextSize(panel.title, font, 0.55, 1, &base);
  cv::putText(canvas, panel.title, cv::Point(plot.x + (plot.width - size.width) / 2, area.y + 25), font, 0.55, black, 1,
              cv::LINE_AA);
  // y label, rotated: draw into a strip and rotate it.
  size = cv::getTextSize(panel.y_label, font, 0.5, 1, &base);
  cv::Mat strip(size.height + base + 6, size.width + 6, canvas.type(), cv::Scalar(255, 255, 255));
  cv::putText(strip, panel.y_label, cv::Point(3, size.height + 2), font, 0.5, black, 1, cv::LINE_AA);
  cv::Mat rotated;
  cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int ry = std::max(area.y, plot.y + (plot.height - rotated.rows) / 2);
  const cv::Rect target(area.x + 5, ry, rotated.cols, std::min(rotated.rows, canvas.rows - ry));
  rotated(cv::Rect(0, 0, target.width, target.height)).copyTo(canvas(target));
  // Legend, top left inside the plot.
  int ly = plot.y + 18;
  for (const auto& c : panel.curves) {
    cv::line(canvas, cv::Point(plot.x + 10, ly - 4), cv::Point(plot.x + 40, ly - 4), c.colour, 2, cv::LINE_AA);
    cv::putText(canvas, c.label, cv::Point(plot.x + 48, ly), font, 0.45, black, 1, cv::LINE_AA);
    ly += 20;
  }
}

}  // namespace

cv::Mat draw_panels(const std::vector<PlotPanel>& panels, int panel_width, int height) {
  cv::Mat canvas(height, panel_width * static_cast<int>(panels.size()), CV_8UC3, cv::Scalar(255, 255, 255));
  for (std::size_t i = 0; i < panels.size(); ++i) {
    draw_panel(canvas, cv::Rect(static_cast<int>(i) * panel_width, 0, panel_width, height), panels[i]);
  }
  return canvas;
}

}  // namespace rgbdt::apps
