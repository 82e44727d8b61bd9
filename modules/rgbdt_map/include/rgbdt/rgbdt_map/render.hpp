#pragma once
/// \file
/// Pictures of a map, because users look at maps rather than read them (paper Fig. 16):
/// a top view (orthographic, looking down the world z axis) and a perspective view from
/// behind and above the map, in RGB or in temperature (with a colour bar). Voxels are
/// drawn as squares of their projected size with a z-buffer, so near surfaces hide far ones.
#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "rgbdt/rgbdt_map/voxel_map.hpp"

namespace rgbdt::rgbdt_map {

enum class RenderMode { kRgb, kThermal };

struct RenderOptions {
  int width_px = 1600;
  int height_px = 1200;
  double voxel_size_m = 0.05;        ///< drawn size of each point [m]
  double perspective_fov_deg = 60.0;  ///< horizontal field of view of the perspective view
  /// Thermal colour scale [K]; when min >= max, the 2nd and 98th percentiles of the map.
  double thermal_min_k = 0.0, thermal_max_k = 0.0;
  std::string validate() const;
};

/// Top view; voxels without the mode's colour are drawn dark grey (geometry only).
/// Returns an 8-bit BGR image. Throws std::invalid_argument on empty input or bad options.
cv::Mat render_top_view(const std::vector<MapPoint>& points, RenderMode mode, const RenderOptions& options = {});
/// Perspective view from behind the map's start, 35 deg down, framing the whole map.
cv::Mat render_perspective(const std::vector<MapPoint>& points, RenderMode mode, const RenderOptions& options = {});

}  // namespace rgbdt::rgbdt_map
