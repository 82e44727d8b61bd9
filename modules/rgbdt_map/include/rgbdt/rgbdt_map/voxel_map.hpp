#pragma once
/// \file
/// The RGB-Depth-Thermal map: a hash map of voxels keeping, per voxel, the mean position of
/// the points that fell in it, their mean colour, the observation count and the last time
/// it was seen, plus one thermal layer per session (day and night sessions of the same
/// place fuse into one map whose temperatures stay apart).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "rgbdt/rgbdt_map/colorize.hpp"

namespace rgbdt::rgbdt_map {

struct VoxelMapOptions {
  double resolution_m = 0.05;  ///< voxel edge [m]; the paper's maps are ~1.2 M points at ~5 cm
  std::string validate() const;
};

struct Voxel {
  Eigen::Vector3f mean_position_m = Eigen::Vector3f::Zero();  ///< world frame [m]
  Eigen::Vector3f mean_rgb = Eigen::Vector3f::Zero();         ///< 0..255, valid if color_count > 0
  std::uint32_t count = 0;        ///< points that fell in the voxel
  std::uint32_t color_count = 0;  ///< of which had an RGB colour
  double last_time_s = 0.0;       ///< latest observation [s]
};

struct ThermalCell {
  float mean_k = 0.0f;  ///< mean temperature [K]
  std::uint32_t count = 0;
};

/// One voxel as exported: mean position, colour, temperature of one layer.
struct MapPoint {
  Eigen::Vector3f position_m = Eigen::Vector3f::Zero();
  std::array<std::uint8_t, 3> rgb{0, 0, 0};  ///< valid if has_rgb
  bool has_rgb = false;
  float temperature_k = 0.0f;  ///< NaN if the layer has no temperature here
  std::uint32_t count = 0;
  double last_time_s = 0.0;
};

class VoxelMap {
 public:
  using Key = std::uint64_t;

  /// Throws std::invalid_argument if options.validate() fails.
  explicit VoxelMap(const VoxelMapOptions& options = {});

  /// Adds a thermal layer (e.g. one per session: "day", "night") and returns its index.
  int add_thermal_layer(const std::string& name);
  int thermal_layers() const { return static_cast<int>(layer_names_.size()); }
  const std::string& thermal_layer_name(int layer) const;

  /// Adds points given in the world frame [m]. `rgb` and `temperatures` (either may be
  /// null) are per point, as colorize.hpp returns them; only points whose status is
  /// kColored contribute a colour / temperature. Temperatures go to `thermal_layer`.
  /// Throws std::invalid_argument on size mismatches or an unknown layer.
  void insert(const std::vector<Eigen::Vector3f>& points_world, const RgbColors* rgb,
              const Temperatures* temperatures, int thermal_layer, double time_s);

  std::size_t size() const { return voxels_.size(); }
  double resolution_m() const { return options_.resolution_m; }
  Key key_of(const Eigen::Vector3f& point_world) const;
  const std::unordered_map<Key, Voxel>& voxels() const { return voxels_; }
  const std::unordered_map<Key, ThermalCell>& thermal_layer(int layer) const;

  /// Every voxel with at least min_count points; temperature from `thermal_layer`
  /// (-1: none, all NaN).
  std::vector<MapPoint> points(int thermal_layer = 0, std::uint32_t min_count = 1) const;

  /// Approximate heap memory used [bytes] (nodes and buckets of the hash maps).
  std::size_t memory_bytes() const;

 private:
  VoxelMapOptions options_;
  float inv_resolution_;
  std::unordered_map<Key, Voxel> voxels_;
  std::vector<std::unordered_map<Key, ThermalCell>> layers_;
  std::vector<std::string> layer_names_;
};

}  // namespace rgbdt::rgbdt_map
