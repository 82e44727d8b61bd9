#include "detections_table.hpp"

#include <algorithm>
#include <cstdio>
#include <sstream>

namespace rgbdt::calibrate {

namespace {

/// The cells of a row in the CSV's column order (empty where a value does not apply).
std::vector<std::string> cells(const DetectionRow& r) {
  const auto num = [](double v, const char* format) {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return std::string(buf);
  };
  std::vector<std::string> c = {std::to_string(r.view),
                                std::to_string(r.hole),
                                num(r.lidar_center.x(), "%.4f"),
                                num(r.lidar_center.y(), "%.4f"),
                                num(r.lidar_center.z(), "%.4f"),
                                num(r.lidar_radius_m, "%.4f"),
                                r.radius_measured ? "yes" : "no"};
  if (r.image_ellipse) {
    const cv::RotatedRect& e = *r.image_ellipse;
    c.push_back(num(e.center.x, "%.2f"));
    c.push_back(num(e.center.y, "%.2f"));
    c.push_back(num(std::max(e.size.width, e.size.height), "%.2f"));
    c.push_back(num(std::min(e.size.width, e.size.height), "%.2f"));
    c.push_back(num(e.angle, "%.1f"));
  } else {
    c.insert(c.end(), 5, "");
  }
  c.push_back(r.lidar_method);
  c.push_back(r.view_rms_px ? num(*r.view_rms_px, "%.3f") : "");
  c.push_back(r.used ? (*r.used ? "yes" : "no") : "");
  return c;
}

const char* const kColumns[] = {"view",           "hole",           "lidar_x_m",        "lidar_y_m",
                                "lidar_z_m",      "lidar_radius_m", "radius_measured",  "image_u_px",
                                "image_v_px",     "ellipse_major_px", "ellipse_minor_px", "ellipse_angle_deg",
                                "lidar_method",   "view_rms_px",    "used"};

}  // namespace

std::string format_detections_csv(const std::vector<DetectionRow>& rows) {
  std::ostringstream os;
  for (size_t i = 0; i < std::size(kColumns); ++i) os << (i ? "," : "") << kColumns[i];
  os << "\n";
  for (const auto& r : rows) {
    const auto c = cells(r);
    for (size_t i = 0; i < c.size(); ++i) {
      // The method names hold spaces and parentheses, never commas or quotes; quote anyway.
      const bool quote = c[i].find_first_of(", ()") != std::string::npos;
      os << (i ? "," : "") << (quote ? "\"" + c[i] + "\"" : c[i]);
    }
    os << "\n";
  }
  return os.str();
}

std::string format_detections_markdown(const std::vector<DetectionRow>& rows) {
  std::ostringstream os;
  os << "|";
  for (const char* c : kColumns) os << " " << c << " |";
  os << "\n|";
  for (size_t i = 0; i < std::size(kColumns); ++i) os << "---|";
  os << "\n";
  for (const auto& r : rows) {
    os << "|";
    for (const auto& c : cells(r)) os << " " << c << " |";
    os << "\n";
  }
  return os.str() + "\n";
}

}  // namespace rgbdt::calibrate
