#pragma once
/// \file
/// Map files for viewers and planners:
///   - PLY, binary little endian, vertex fields x y z (float) red green blue (uchar)
///     temperature (float, kelvin, NaN where unknown): opens in CloudCompare and MeshLab,
///     with temperature as a scalar field;
///   - PCD, binary, fields x y z rgb temperature (PCL, CloudCompare);
///   - OctoMap: `map.bt` occupancy built by ray insertion from the sensor origin of every
///     scan (free space is known), `map_rgb.ot` (octomap::ColorOcTree) and
///     `map_thermal.ot` (ThermalOcTree, see thermal_octree.hpp).
/// Every writer writes a temporary sibling, checks every write and the close, and renames
/// it into place: it throws rgbdt::core::Error naming the file when it cannot write (a full
/// disk included) and leaves no partial file. Readers name the file and what was expected.
/// An empty map (or one without any colour) gives valid trees without nodes.
#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "rgbdt/rgbdt_map/voxel_map.hpp"

namespace rgbdt::rgbdt_map {

/// Writes map points; points without RGB are written with `uncolored_rgb` (PLY has no
/// "missing" colour; their temperature is still written). Use VoxelMap::points and filter
/// on has_rgb to leave them out instead.
void write_ply(const std::string& path, const std::vector<MapPoint>& points,
               std::array<std::uint8_t, 3> uncolored_rgb = {128, 128, 128});
/// Reads a binary little endian PLY with float x y z, uchar red green blue and float
/// temperature vertices (what write_ply writes). has_rgb is true for every point.
std::vector<MapPoint> read_ply(const std::string& path);

/// PCD (binary) with fields x y z rgb temperature; same conventions as write_ply.
void write_pcd(const std::string& path, const std::vector<MapPoint>& points,
               std::array<std::uint8_t, 3> uncolored_rgb = {128, 128, 128});
std::vector<MapPoint> read_map_pcd(const std::string& path);

struct OccupancyOptions {
  double resolution_m = 0.05;  ///< octree leaf size [m]
  /// Free space is carved along each ray up to this range; farther points are still
  /// inserted as occupied, without carving. Ray casting costs one step per cell crossed,
  /// so a 40 m ray at 5 cm costs 800: 15 m keeps a 1.2 M-point map within seconds and
  /// covers where a cart plans. < 0: carve whole rays. [m]
  double max_free_range_m = 15.0;
  /// One ray carves free space per cell of this size holding end points (all end points
  /// are still marked occupied at resolution_m): near the sensor, where points are dense,
  /// this removes most rays; free space is then exact except within this distance of
  /// surfaces. <= resolution_m: one ray per end cell. [m]
  double free_space_voxel_m = 0.25;
  /// Free space is written in octree cells of this size (rounded down to resolution_m
  /// times a power of two, at most 16x) wherever the tree knows no surface inside the cell
  /// (no finer detail, this scan's end points included); elsewhere leaf by leaf, exactly.
  /// At 5 cm leaves, 20 cm cells hold 64x fewer free nodes: a 10 M-point session fits in
  /// memory, and the free space between rays has no holes. The price: where a surface
  /// has not been seen yet, up to one such cell behind it may be marked free.
  /// <= resolution_m: every free cell at resolution_m (octomap's insertPointCloud). [m]
  double free_space_cell_m = 0.2;
  double prob_hit = 0.7;       ///< octomap sensor model (its defaults)
  double prob_miss = 0.4;
  std::string validate() const;
};

/// Occupancy octree built scan by scan: every point casts a ray from the sensor origin
/// that marks the cells it crosses free (see free_space_cell_m) and its end cell
/// occupied. Each call is one batch,
/// with octomap's insertPointCloud semantics (every cell updated once per batch; a cell
/// both crossed and hit is occupied; rays deduplicated per end cell as its `discretize`),
/// applied in octree order so that consecutive updates share their path from the root.
/// Inner nodes are updated once, when the tree is written or tree() is asked for.
class OccupancyMapBuilder {
 public:
  explicit OccupancyMapBuilder(const OccupancyOptions& options = {});
  /// One scan seen from one sensor origin (world frame) [m].
  void insert_scan(const std::vector<Eigen::Vector3f>& points_world, const Eigen::Vector3d& sensor_origin_world);
  /// One tilt in one batch, each point's ray cast from where the sensor was when it was
  /// measured (one origin per point, see sensor_origins_in_world in registration.hpp).
  /// Throws std::invalid_argument if the sizes differ.
  void insert_scan(const std::vector<Eigen::Vector3f>& points_world,
                   const std::vector<Eigen::Vector3f>& sensor_origins_world);
  octomap::OcTree& tree();
  /// Writes the maximum-likelihood binary tree (.bt).
  void write_bt(const std::string& path);

 private:
  template <typename OriginOf>
  void insert_rays(const std::vector<Eigen::Vector3f>& points_world, OriginOf&& origin_of);

  OccupancyOptions options_;
  std::unique_ptr<octomap::OcTree> tree_;
  bool inner_nodes_stale_ = false;
  // Reused between batches (a tilt casts ~10^6 ray cells).
  std::vector<std::uint64_t> occupied_codes_, free_codes_, merged_codes_, scratch_;
  int free_space_levels_up_ = 0;     ///< free space is written this many levels above the leaves
  std::size_t nodes_after_prune_ = 1 << 16;  ///< octree size after the last prune (grows 2x before the next)
};

/// ColorOcTree of the map's coloured voxels (occupied, mean colour) as a full .ot file.
void write_color_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m);
/// ThermalOcTree of the voxels with a temperature, as a full .ot file.
void write_thermal_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m);

}  // namespace rgbdt::rgbdt_map
