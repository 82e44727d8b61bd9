#include "rgbdt/rgbdt_map/export.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <octomap/ColorOcTree.h>
#include <pcl/io/pcd_io.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_set>

#include "rgbdt/core/error.hpp"
#include "rgbdt/rgbdt_map/thermal_octree.hpp"

namespace rgbdt::rgbdt_map {
namespace {

struct EIGEN_ALIGN16 PointXYZRGBT {
  PCL_ADD_POINT4D;
  PCL_ADD_RGB;
  float temperature;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

std::array<std::uint8_t, 3> color_of(const MapPoint& p, const std::array<std::uint8_t, 3>& uncolored) {
  return p.has_rgb ? p.rgb : uncolored;
}

void ensure_parent(const std::string& path) {
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
  }
}

}  // namespace
}  // namespace rgbdt::rgbdt_map

POINT_CLOUD_REGISTER_POINT_STRUCT(rgbdt::rgbdt_map::PointXYZRGBT,
                                  (float, x, x)(float, y, y)(float, z, z)(float, rgb, rgb)(float, temperature,
                                                                                           temperature))

namespace rgbdt::rgbdt_map {

void write_ply(const std::string& path, const std::vector<MapPoint>& points, std::array<std::uint8_t, 3> uncolored) {
  static_assert(sizeof(float) == 4, "PLY float is 4 bytes");
  ensure_parent(path);
  std::ofstream out(path, std::ios::binary);
  if (!out) throw core::Error(path, "cannot open for writing");
  out << "ply\nformat binary_little_endian 1.0\ncomment rgbdt map; temperature in kelvin, nan = unknown\n"
      << "element vertex " << points.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "property float temperature\nend_header\n";
  std::vector<char> buffer(points.size() * 19);
  char* w = buffer.data();
  for (const MapPoint& p : points) {
    // x86 and ARM are little endian; the layout below is the file's.
    std::memcpy(w, p.position_m.data(), 12);
    const auto c = color_of(p, uncolored);
    std::memcpy(w + 12, c.data(), 3);
    std::memcpy(w + 15, &p.temperature_k, 4);
    w += 19;
  }
  out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  if (!out) throw core::Error(path, "write failed (disk full?)");
}

std::vector<MapPoint> read_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path, "cannot open PLY file");
  std::string line;
  std::getline(in, line);
  if (line != "ply") throw core::Error(path, "does not start with 'ply'");
  std::size_t count = 0;
  std::vector<std::string> properties;
  bool binary_le = false;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream ss(line);
    std::string word;
    ss >> word;
    if (word == "format") {
      std::string format;
      ss >> format;
      binary_le = format == "binary_little_endian";
    } else if (word == "element") {
      std::string name;
      ss >> name >> count;
      if (name != "vertex") throw core::Error(path, "element '" + name + "' unsupported, expected only vertex");
    } else if (word == "property") {
      std::string type, name;
      ss >> type >> name;
      properties.push_back(type + " " + name);
    }
  }
  const std::vector<std::string> expected = {"float x",         "float y",        "float z",
                                             "uchar red",       "uchar green",    "uchar blue",
                                             "float temperature"};
  if (!binary_le || properties != expected) {
    throw core::Error(path, "expected binary_little_endian vertices with float x y z, uchar red green blue, "
                            "float temperature");
  }
  std::vector<char> buffer(count * 19);
  in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  if (static_cast<std::size_t>(in.gcount()) != buffer.size()) {
    throw core::Error(path, "truncated: header announces " + std::to_string(count) + " vertices");
  }
  std::vector<MapPoint> points(count);
  const char* r = buffer.data();
  for (MapPoint& p : points) {
    std::memcpy(p.position_m.data(), r, 12);
    std::memcpy(p.rgb.data(), r + 12, 3);
    std::memcpy(&p.temperature_k, r + 15, 4);
    p.has_rgb = true;
    r += 19;
  }
  return points;
}

void write_pcd(const std::string& path, const std::vector<MapPoint>& points, std::array<std::uint8_t, 3> uncolored) {
  ensure_parent(path);
  pcl::PointCloud<PointXYZRGBT> cloud;
  cloud.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    auto& q = cloud[i];
    q.x = points[i].position_m.x();
    q.y = points[i].position_m.y();
    q.z = points[i].position_m.z();
    const auto c = color_of(points[i], uncolored);
    q.r = c[0];
    q.g = c[1];
    q.b = c[2];
    q.a = 255;
    q.temperature = points[i].temperature_k;
  }
  cloud.width = static_cast<std::uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = false;
  if (pcl::io::savePCDFileBinary(path, cloud) != 0) throw core::Error(path, "cannot write PCD");
}

std::vector<MapPoint> read_map_pcd(const std::string& path) {
  if (!std::filesystem::exists(path)) throw core::Error(path, "PCD file does not exist");
  pcl::PointCloud<PointXYZRGBT> cloud;
  if (pcl::io::loadPCDFile(path, cloud) != 0) {
    throw core::Error(path, "cannot read as PCD with fields x y z rgb temperature");
  }
  std::vector<MapPoint> points(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    points[i].position_m = Eigen::Vector3f(cloud[i].x, cloud[i].y, cloud[i].z);
    points[i].rgb = {cloud[i].r, cloud[i].g, cloud[i].b};
    points[i].has_rgb = true;
    points[i].temperature_k = cloud[i].temperature;
  }
  return points;
}

std::string OccupancyOptions::validate() const {
  std::ostringstream os;
  if (!(resolution_m > 0.0)) os << "resolution_m = " << resolution_m << ", expected > 0; ";
  if (!(prob_hit > 0.5 && prob_hit < 1.0)) os << "prob_hit = " << prob_hit << ", expected in (0.5, 1); ";
  if (!(free_space_voxel_m >= 0.0)) os << "free_space_voxel_m = " << free_space_voxel_m << ", expected >= 0; ";
  if (!(prob_miss > 0.0 && prob_miss < 0.5)) os << "prob_miss = " << prob_miss << ", expected in (0, 0.5); ";
  return os.str();
}

OccupancyMapBuilder::OccupancyMapBuilder(const OccupancyOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("OccupancyOptions: " + why);
  tree_ = std::make_unique<octomap::OcTree>(options.resolution_m);
  tree_->setProbHit(options.prob_hit);
  tree_->setProbMiss(options.prob_miss);
}

void OccupancyMapBuilder::insert_scan(const std::vector<Eigen::Vector3f>& points_world,
                                      const Eigen::Vector3d& origin) {
  const octomap::point3d sensor(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                                static_cast<float>(origin.z()));
  const double max_free = options_.max_free_range_m;
  const bool coarse = options_.free_space_voxel_m > options_.resolution_m;
  const float inv_coarse = coarse ? static_cast<float>(1.0 / options_.free_space_voxel_m) : 0.0f;
  std::unordered_set<std::uint64_t> carved;
  octomap::Pointcloud rays;
  rays.reserve(points_world.size());
  std::vector<octomap::point3d> occupied_only;
  for (const auto& p : points_world) {
    if (!p.allFinite()) continue;
    const octomap::point3d q(p.x(), p.y(), p.z());
    // Points beyond the carving range carve up to it (octomap truncates their rays) and are
    // marked occupied separately.
    const bool far = max_free > 0.0 && (q - sensor).norm() > max_free;
    bool carve = true;
    if (coarse) {
      std::uint64_t key = 0;
      for (int a = 0; a < 3; ++a) {
        key = key * 2097143u + static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(p[a] * inv_coarse)) + (1 << 20));
      }
      carve = carved.insert(key).second;
    }
    if (carve) rays.push_back(q);
    if (far || !carve) occupied_only.push_back(q);
  }
  // Lazy: inner nodes are brought up to date once, before the tree is used.
  tree_->insertPointCloud(rays, sensor, max_free, /*lazy_eval=*/true, /*discretize=*/true);
  for (const auto& q : occupied_only) tree_->updateNode(q, true, /*lazy_eval=*/true);
  inner_nodes_stale_ = true;
}

octomap::OcTree& OccupancyMapBuilder::tree() {
  if (inner_nodes_stale_) {
    tree_->updateInnerOccupancy();
    inner_nodes_stale_ = false;
  }
  return *tree_;
}

void OccupancyMapBuilder::write_bt(const std::string& path) {
  ensure_parent(path);
  tree();
  if (!tree_->writeBinary(path)) throw core::Error(path, "cannot write OctoMap binary tree");
}

void write_color_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m) {
  ensure_parent(path);
  octomap::ColorOcTree tree(resolution_m);
  for (const MapPoint& p : points) {
    if (!p.has_rgb) continue;
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(octomap::point3d(p.position_m.x(), p.position_m.y(), p.position_m.z()), key)) continue;
    tree.updateNode(key, true, /*lazy_eval=*/true);
    tree.setNodeColor(key, p.rgb[0], p.rgb[1], p.rgb[2]);
  }
  tree.updateInnerOccupancy();
  if (!tree.write(path)) throw core::Error(path, "cannot write OctoMap ColorOcTree");
}

void write_thermal_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m) {
  ensure_parent(path);
  ThermalOcTree tree(resolution_m);
  for (const MapPoint& p : points) {
    if (std::isnan(p.temperature_k)) continue;
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(octomap::point3d(p.position_m.x(), p.position_m.y(), p.position_m.z()), key)) continue;
    tree.updateNode(key, true, /*lazy_eval=*/true);
    tree.set_node_temperature(key, p.temperature_k);
  }
  tree.update_inner_nodes();
  if (!tree.write(path)) throw core::Error(path, "cannot write ThermalOcTree");
}

}  // namespace rgbdt::rgbdt_map
