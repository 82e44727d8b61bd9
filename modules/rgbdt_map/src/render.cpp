#include "rgbdt/rgbdt_map/render.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace rgbdt::rgbdt_map {
namespace {

const cv::Vec3b kBackground(40, 40, 40);
const cv::Vec3b kUncolored(90, 90, 90);
constexpr int kBarWidthPx = 110;  ///< colour bar and its labels, right of thermal renders

struct Scale {
  double min_k, max_k;
};

Scale thermal_scale(const std::vector<MapPoint>& points, const RenderOptions& options) {
  if (options.thermal_min_k < options.thermal_max_k) return {options.thermal_min_k, options.thermal_max_k};
  std::vector<float> t;
  for (const auto& p : points) {
    if (!std::isnan(p.temperature_k)) t.push_back(p.temperature_k);
  }
  if (t.empty()) return {273.15, 313.15};
  auto pct = [&](double q) {
    const std::size_t k = static_cast<std::size_t>(q * (t.size() - 1));
    std::nth_element(t.begin(), t.begin() + k, t.end());
    return static_cast<double>(t[k]);
  };
  Scale s{pct(0.02), pct(0.98)};
  if (s.max_k - s.min_k < 1.0) {
    const double mid = 0.5 * (s.min_k + s.max_k);
    s = {mid - 0.5, mid + 0.5};
  }
  return s;
}

/// Inferno colour map of OpenCV, as a 256-entry table.
cv::Mat thermal_lut() {
  cv::Mat ramp(256, 1, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(i) = static_cast<std::uint8_t>(i);
  cv::Mat colored;
  cv::applyColorMap(ramp, colored, cv::COLORMAP_INFERNO);
  return colored;
}

cv::Vec3b color_of(const MapPoint& p, RenderMode mode, const Scale& scale, const cv::Mat& lut) {
  if (mode == RenderMode::kRgb) {
    return p.has_rgb ? cv::Vec3b(p.rgb[2], p.rgb[1], p.rgb[0]) : kUncolored;
  }
  if (std::isnan(p.temperature_k)) return kUncolored;
  const double s = (p.temperature_k - scale.min_k) / (scale.max_k - scale.min_k);
  return lut.at<cv::Vec3b>(std::clamp(static_cast<int>(std::lround(255.0 * s)), 0, 255));
}

/// Draws squares with a z-buffer; `project` gives pixel, depth (smaller is nearer) and
/// half-size in pixels, or false to skip the point.
template <typename Project>
cv::Mat draw(const std::vector<MapPoint>& points, RenderMode mode, const RenderOptions& options, Project project) {
  cv::Mat image(options.height_px, options.width_px, CV_8UC3, cv::Scalar(kBackground[0], kBackground[1], kBackground[2]));
  cv::Mat depth(options.height_px, options.width_px, CV_32FC1, cv::Scalar(std::numeric_limits<float>::infinity()));
  const Scale scale = thermal_scale(points, options);
  const cv::Mat lut = thermal_lut();
  for (const auto& p : points) {
    double u, v, z, half;
    if (!project(p.position_m.cast<double>(), &u, &v, &z, &half)) continue;
    const cv::Vec3b c = color_of(p, mode, scale, lut);
    const int h = std::max(0, static_cast<int>(std::floor(half)));
    const int cx = static_cast<int>(std::lround(u)), cy = static_cast<int>(std::lround(v));
    for (int y = std::max(0, cy - h); y <= std::min(options.height_px - 1, cy + h); ++y) {
      for (int x = std::max(0, cx - h); x <= std::min(options.width_px - 1, cx + h); ++x) {
        float& d = depth.at<float>(y, x);
        if (z < d) {
          d = static_cast<float>(z);
          image.at<cv::Vec3b>(y, x) = c;
        }
      }
    }
  }
  if (mode == RenderMode::kThermal) {
    // Colour bar with labels in kelvin and degrees Celsius.
    cv::Mat with_bar(image.rows, image.cols + kBarWidthPx, CV_8UC3, cv::Scalar(kBackground[0], kBackground[1], kBackground[2]));
    image.copyTo(with_bar(cv::Rect(0, 0, image.cols, image.rows)));
    const int top = 40, bottom = image.rows - 40, x0 = image.cols + 15;
    for (int y = top; y <= bottom; ++y) {
      const int index = static_cast<int>(std::lround(255.0 * (bottom - y) / (bottom - top)));
      cv::line(with_bar, {x0, y}, {x0 + 25, y}, cv::Scalar(lut.at<cv::Vec3b>(index)), 1);
    }
    for (int k = 0; k <= 4; ++k) {
      const double kelvin = scale.min_k + (scale.max_k - scale.min_k) * k / 4.0;
      const int y = bottom - (bottom - top) * k / 4;
      std::ostringstream label;
      label.precision(1);
      label << std::fixed << kelvin - 273.15 << " C";
      cv::putText(with_bar, label.str(), {x0 + 30, y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(230, 230, 230), 1,
                  cv::LINE_AA);
    }
    return with_bar;
  }
  return image;
}

struct Bounds {
  Eigen::Vector3d lo, hi;
};
Bounds bounds_of(const std::vector<MapPoint>& points) {
  if (points.empty()) throw std::invalid_argument("render: the map has no points");
  Bounds b{Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()),
           Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity())};
  for (const auto& p : points) {
    b.lo = b.lo.cwiseMin(p.position_m.cast<double>());
    b.hi = b.hi.cwiseMax(p.position_m.cast<double>());
  }
  return b;
}

void check(const RenderOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("RenderOptions: " + why);
}

}  // namespace

std::string RenderOptions::validate() const {
  std::ostringstream os;
  if (width_px < 16 || height_px < 16) os << "image " << width_px << "x" << height_px << " px, expected >= 16x16; ";
  if (!(voxel_size_m > 0.0)) os << "voxel_size_m = " << voxel_size_m << ", expected > 0; ";
  if (!(perspective_fov_deg > 1.0 && perspective_fov_deg < 170.0)) {
    os << "perspective_fov_deg = " << perspective_fov_deg << ", expected in (1, 170); ";
  }
  return os.str();
}

cv::Mat render_top_view(const std::vector<MapPoint>& points, RenderMode mode, const RenderOptions& options) {
  check(options);
  const Bounds b = bounds_of(points);
  const double margin = 0.05;
  const double sx = (b.hi.x() - b.lo.x()) * (1 + 2 * margin) + 1e-6;
  const double sy = (b.hi.y() - b.lo.y()) * (1 + 2 * margin) + 1e-6;
  const double px_per_m = std::min(options.width_px / sy, options.height_px / sx);
  const Eigen::Vector3d centre = 0.5 * (b.lo + b.hi);
  const double half = 0.5 * options.voxel_size_m * px_per_m;
  // World x points up in the picture and y to the left, as a map seen from above.
  return draw(points, mode, options, [&](const Eigen::Vector3d& p, double* u, double* v, double* z, double* h) {
    *u = 0.5 * options.width_px - (p.y() - centre.y()) * px_per_m;
    *v = 0.5 * options.height_px - (p.x() - centre.x()) * px_per_m;
    *z = -p.z();  // highest point wins
    *h = half;
    return true;
  });
}

cv::Mat render_perspective(const std::vector<MapPoint>& points, RenderMode mode, const RenderOptions& options) {
  check(options);
  const Bounds b = bounds_of(points);
  const Eigen::Vector3d centre = 0.5 * (b.lo + b.hi);
  const double radius = std::max(1.0, 0.5 * (b.hi - b.lo).norm());
  const double fov = options.perspective_fov_deg * M_PI / 180.0;
  const double f = 0.5 * options.width_px / std::tan(0.5 * fov);
  // Eye behind the map along -x, raised so it looks down 35 deg, far enough to frame it.
  const double pitch = 35.0 * M_PI / 180.0;
  const double distance = radius / std::sin(0.5 * fov) * 0.9;
  const Eigen::Vector3d forward(std::cos(pitch), 0.0, -std::sin(pitch));
  const Eigen::Vector3d eye = centre - distance * forward;
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  return draw(points, mode, options, [&](const Eigen::Vector3d& p, double* u, double* v, double* z, double* h) {
    const Eigen::Vector3d d = p - eye;
    const double depth = d.dot(forward);
    if (depth < 0.1) return false;
    *u = 0.5 * options.width_px + f * d.dot(right) / depth;
    *v = 0.5 * options.height_px + f * d.dot(down) / depth;
    *z = depth;
    *h = 0.5 * f * options.voxel_size_m / depth;
    return true;
  });
}

}  // namespace rgbdt::rgbdt_map
