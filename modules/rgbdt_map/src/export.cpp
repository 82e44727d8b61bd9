#include "rgbdt/rgbdt_map/export.hpp"

#include "rgbdt/cloud/point_types.hpp"  // defines PCL_NO_PRECOMPILE before PCL's headers

#include <octomap/ColorOcTree.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <unordered_set>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
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

// Writes a file through `write(std::ostream&)` (false: the writer failed) into a temporary
// sibling, checks the stream after the last byte, the flush and the close, and only then
// renames it over `path`: a full disk or an unwritable folder throws naming `path` and
// leaves no file there.
template <typename Write>
void write_checked(const std::string& path, const char* what, Write&& write) {
  ensure_parent(path);
  core::TempOutput temp(path);
  {
    std::ofstream out(temp.temp_path(), std::ios::binary);
    if (!out) throw core::Error(path, std::string("cannot open for writing: ") + std::strerror(errno));
    const bool written = write(out);
    out.flush();
    if (!written || !out) {
      throw core::Error(path, std::string(what) + ": write failed (" + std::strerror(errno) +
                                  "; disk full?), nothing was written");
    }
    out.close();
    if (!out) throw core::Error(path, std::string(what) + ": close failed (" + std::strerror(errno) + ")");
  }
  temp.commit();
}

}  // namespace
}  // namespace rgbdt::rgbdt_map

POINT_CLOUD_REGISTER_POINT_STRUCT(rgbdt::rgbdt_map::PointXYZRGBT,
                                  (float, x, x)(float, y, y)(float, z, z)(float, rgb, rgb)(float, temperature,
                                                                                           temperature))

namespace rgbdt::rgbdt_map {

void write_ply(const std::string& path, const std::vector<MapPoint>& points, std::array<std::uint8_t, 3> uncolored) {
  static_assert(sizeof(float) == 4, "PLY float is 4 bytes");
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
  write_checked(path, "PLY", [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\ncomment rgbdt map; temperature in kelvin, nan = unknown\n"
        << "element vertex " << points.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        << "property float temperature\nend_header\n";
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    return static_cast<bool>(out);
  });
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
  // PCL's header, and its binary layout (the named fields packed in order, padding left
  // out), written through a checked stream: PCL's own writer maps the file into memory,
  // where a full disk is a signal rather than an error.
  std::vector<pcl::PCLPointField> fields;
  for (const pcl::PCLPointField& f : pcl::getFields<PointXYZRGBT>()) {
    if (f.name != "_") fields.push_back(f);
  }
  std::size_t point_bytes = 0;
  for (const pcl::PCLPointField& f : fields) point_bytes += f.count * pcl::getFieldSize(f.datatype);
  std::vector<char> buffer(cloud.size() * point_bytes);
  char* w = buffer.data();
  for (const PointXYZRGBT& q : cloud) {
    for (const pcl::PCLPointField& f : fields) {
      const std::size_t bytes = f.count * pcl::getFieldSize(f.datatype);
      std::memcpy(w, reinterpret_cast<const char*>(&q) + f.offset, bytes);
      w += bytes;
    }
  }
  const std::string header = pcl::PCDWriter::generateHeader(cloud) + "DATA binary\n";
  write_checked(path, "PCD", [&](std::ostream& out) {
    out << header;
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    return static_cast<bool>(out);
  });
}

std::vector<MapPoint> read_map_pcd(const std::string& path) {
  // The checked reader sizes everything from the file before a byte is decoded; PCL then
  // maps the named fields onto the point type.
  const pcl::PCLPointCloud2 blob = cloud::load_pcd_blob(path);
  std::string missing;
  for (const char* name : {"x", "y", "z", "rgb", "temperature"}) {
    const bool found = std::any_of(blob.fields.begin(), blob.fields.end(),
                                   [&](const pcl::PCLPointField& f) { return f.name == name; });
    if (!found) missing += std::string(missing.empty() ? "" : " ") + name;
  }
  if (!missing.empty()) {
    throw core::Error(path, "map PCD lacks the fields " + missing +
                                ", expected x y z rgb temperature (a map written by rgbdt_mapper)");
  }
  pcl::PointCloud<PointXYZRGBT> cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
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
  if (!(free_space_cell_m >= 0.0)) os << "free_space_cell_m = " << free_space_cell_m << ", expected >= 0; ";
  if (!(free_space_voxel_m >= 0.0)) os << "free_space_voxel_m = " << free_space_voxel_m << ", expected >= 0; ";
  if (!(prob_miss > 0.0 && prob_miss < 0.5)) os << "prob_miss = " << prob_miss << ", expected in (0, 0.5); ";
  return os.str();
}

OccupancyMapBuilder::OccupancyMapBuilder(const OccupancyOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("OccupancyOptions: " + why);
  tree_ = std::make_unique<octomap::OcTree>(options.resolution_m);
  // The octree cell closest to (not above) free_space_cell_m: 2^levels_up leaves.
  while (free_space_levels_up_ < 4 &&
         options.resolution_m * (1 << (free_space_levels_up_ + 1)) <= options.free_space_cell_m * 1.0001) {
    ++free_space_levels_up_;
  }
  tree_->setProbHit(options.prob_hit);
  tree_->setProbMiss(options.prob_miss);
}

namespace {

// An octree key (16 bits per axis) as a Morton code, most significant level first: sorted
// codes visit the tree depth first, so consecutive updates share most of their path.
// Level l's 3 bits are octomap's child index there (x + 2y + 4z, octomap's computeChildIdx).
std::uint64_t morton(const octomap::OcTreeKey& key) {
  auto spread = [](std::uint64_t v) {  // bit i -> bit 3i
    v &= 0xffff;
    v = (v | (v << 16)) & 0x0000ff0000ffULL;
    v = (v | (v << 8)) & 0x00f00f00f00fULL;
    v = (v | (v << 4)) & 0x0c30c30c30c3ULL;
    v = (v | (v << 2)) & 0x249249249249ULL;
    return v;
  };
  return spread(key[0]) | (spread(key[1]) << 1) | (spread(key[2]) << 2);
}

// LSD radix sort of 48-bit codes, 16 bits per pass, then duplicates removed: the batch holds
// ~10^6 ray cells, mostly repeats near the sensor.
void sort_unique(std::vector<std::uint64_t>& codes, std::vector<std::uint64_t>& scratch) {
  scratch.resize(codes.size());
  std::vector<std::uint32_t> count(1 << 16);
  for (int pass = 0; pass < 3; ++pass) {
    const int shift = 16 * pass;
    std::fill(count.begin(), count.end(), 0u);
    for (const std::uint64_t c : codes) ++count[(c >> shift) & 0xffff];
    std::uint32_t sum = 0;
    for (auto& n : count) {
      const std::uint32_t here = n;
      n = sum;
      sum += here;
    }
    for (const std::uint64_t c : codes) scratch[count[(c >> shift) & 0xffff]++] = c;
    codes.swap(scratch);
  }
  codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
}

octomap::OcTreeKey key_of(std::uint64_t code, int levels) {
  octomap::OcTreeKey key;
  for (int a = 0; a < 3; ++a) {
    std::uint16_t k = 0;
    for (int l = 0; l < levels; ++l) k |= static_cast<std::uint16_t>(((code >> (3 * l + a)) & 1u) << (l + 16 - levels));
    key[a] = k;
  }
  return key;
}

// Applies one batch of log-odds updates to the nodes at depth `levels` (16: leaves) whose
// Morton codes (3 bits per level) are `codes`, sorted and unique, exactly as octomap's
// updateNode(key, log_odds, lazy_eval = true) does one key at a time (same node creation,
// same expansion of pruned nodes, same clamping), but walking down only from the deepest
// node shared with the previous key instead of from the root. A node updated above the
// leaves has no children: octomap reads it as a pruned leaf covering its whole cube.
void apply_sorted(octomap::OcTree& tree, const std::vector<std::uint64_t>& codes, int levels, float log_odds) {
  constexpr int kDepth = 16;
  if (codes.empty()) return;
  std::size_t first = 0;
  if (tree.getRoot() == nullptr) {
    // octomap creates the root on the first update; let it (a leaf update: only used for
    // the first batch, which always holds occupied end points).
    tree.updateNode(key_of(codes[0], levels), log_odds, /*lazy_eval=*/true);
    first = 1;
  }
  const float min_log = tree.getClampingThresMinLog(), max_log = tree.getClampingThresMaxLog();
  std::array<octomap::OcTreeNode*, kDepth + 1> path{};
  std::array<bool, kDepth + 1> created{};
  path[0] = tree.getRoot();
  int valid = 0;  // path[0..valid] belongs to the previous code
  const int bits = 3 * levels;
  for (std::size_t i = first; i < codes.size(); ++i) {
    const std::uint64_t code = codes[i];
    if (i > first) {
      // Levels shared with the previous code: its leading equal 3-bit groups.
      const std::uint64_t diff = code ^ codes[i - 1];
      const int highest = 63 - __builtin_clzll(diff);  // codes are unique: diff != 0
      valid = std::min(valid, (bits - 1 - highest) / 3);
    }
    bool unchanged = false;
    for (int depth = valid; depth < levels; ++depth) {
      octomap::OcTreeNode* node = path[depth];
      const unsigned pos = static_cast<unsigned>((code >> (3 * (levels - 1 - depth))) & 7u);
      bool made = false;
      if (!tree.nodeChildExists(node, pos)) {
        if (!tree.nodeHasChildren(node) && !created[depth]) {
          // A pruned leaf. Already clamped the way this update goes, nothing would change:
          // octomap's updateNode returns early there, and so do we (no expansion).
          const float value = node->getLogOdds();
          if ((log_odds <= 0.0f && value <= min_log) || (log_odds >= 0.0f && value >= max_log)) {
            valid = depth;
            unchanged = true;
            break;
          }
          tree.expandNode(node);  // its children inherit its value
        } else {
          tree.createNodeChild(node, pos);
          made = true;
        }
      }
      path[depth + 1] = tree.getNodeChild(node, pos);
      created[depth + 1] = made;
    }
    if (unchanged) continue;
    valid = levels;
    tree.updateNodeLogOdds(path[levels], log_odds);
  }
}

}  // namespace

void OccupancyMapBuilder::insert_scan(const std::vector<Eigen::Vector3f>& points_world,
                                      const Eigen::Vector3d& origin) {
  insert_rays(points_world, [o = origin.cast<float>()](std::size_t) { return o; });
}

void OccupancyMapBuilder::insert_scan(const std::vector<Eigen::Vector3f>& points_world,
                                      const std::vector<Eigen::Vector3f>& sensor_origins_world) {
  if (sensor_origins_world.size() != points_world.size()) {
    throw std::invalid_argument("OccupancyMapBuilder::insert_scan: " + std::to_string(sensor_origins_world.size()) +
                                " sensor origins for " + std::to_string(points_world.size()) +
                                " points, expected one per point");
  }
  insert_rays(points_world, [&](std::size_t i) { return sensor_origins_world[i]; });
}

template <typename OriginOf>
void OccupancyMapBuilder::insert_rays(const std::vector<Eigen::Vector3f>& points_world, OriginOf&& origin_of) {
  const double max_free = options_.max_free_range_m;
  const bool coarse = options_.free_space_voxel_m > options_.resolution_m;
  const float inv_coarse = coarse ? static_cast<float>(1.0 / options_.free_space_voxel_m) : 0.0f;
  const float inv_fine = static_cast<float>(1.0 / options_.resolution_m);
  std::unordered_set<std::uint64_t> carved;
  auto cell_of = [](const Eigen::Vector3f& p, float inv) {
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      key = key * 2097143u + static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(p[a] * inv)) + (1 << 20));
    }
    return key;
  };
  std::vector<std::uint64_t>& occupied = occupied_codes_;
  std::vector<std::uint64_t>& free = free_codes_;
  occupied.clear();
  free.clear();
  octomap::KeyRay ray;
  std::vector<octomap::OcTreeKey> previous_ray;
  octomap::OcTreeKey key;
  for (std::size_t i = 0; i < points_world.size(); ++i) {
    const Eigen::Vector3f& p = points_world[i];
    if (!p.allFinite()) continue;
    const octomap::point3d end(p.x(), p.y(), p.z());
    if (tree_->coordToKeyChecked(end, key)) occupied.push_back(morton(key));
    // One ray per end cell (octomap's discretize) or per coarse cell: rays to the same
    // cell carve the same cells, up to the cell's size at their end.
    const bool carve = coarse ? carved.insert(cell_of(p, inv_coarse)).second : carved.insert(cell_of(p, inv_fine)).second;
    if (!carve) continue;
    const Eigen::Vector3f o = origin_of(i);
    const octomap::point3d sensor(o.x(), o.y(), o.z());
    octomap::point3d ray_end = end;
    const double range = (end - sensor).norm();
    // Beyond the carving range the ray stops there (octomap's maxrange); its end point is
    // still occupied.
    if (max_free > 0.0 && range > max_free) ray_end = sensor + (end - sensor) * static_cast<float>(max_free / range);
    if (tree_->computeRayKeys(sensor, ray_end, ray)) {
      // Neighbouring rays from one origin cross the same cells for most of their way: skip
      // the cells the previous ray crossed at the same step (a cheap first deduplication,
      // which keeps the batch's buffers small).
      std::size_t step = 0;
      for (auto it = ray.begin(); it != ray.end(); ++it, ++step) {
        if (step < previous_ray.size() && previous_ray[step] == *it) continue;
        free.push_back(morton(*it));
      }
      previous_ray.assign(ray.begin(), ray.end());
    }
  }
  sort_unique(occupied, scratch_);
  sort_unique(free, scratch_);
  // One batch, octomap's rule: a cell both crossed and hit is occupied.
  std::vector<std::uint64_t>& crossed = merged_codes_;
  crossed.clear();
  std::set_difference(free.begin(), free.end(), occupied.begin(), occupied.end(), std::back_inserter(crossed));
  apply_sorted(*tree_, occupied, 16, tree_->getProbHitLog());
  const int coarse_levels = 16 - free_space_levels_up_;
  if (coarse_levels == 16) {
    apply_sorted(*tree_, crossed, 16, tree_->getProbMissLog());
  } else {
    // Free space in cells of 2^levels_up leaves, where no surface is known yet (the tree
    // has no detail there, the end points of this batch included); elsewhere leaf by leaf.
    const int shift = 3 * free_space_levels_up_;
    std::vector<std::uint64_t>& coarse = scratch_;
    coarse.clear();
    std::size_t fine_end = 0;  // the leaf-by-leaf codes are compacted to the front of `crossed`
    for (std::size_t i = 0; i < crossed.size();) {
      const std::uint64_t prefix = crossed[i] >> shift;
      std::size_t j = i;
      while (j < crossed.size() && (crossed[j] >> shift) == prefix) ++j;
      const octomap::OcTreeNode* node = tree_->search(key_of(crossed[i], 16), coarse_levels);
      if (node != nullptr && tree_->nodeHasChildren(node)) {
        while (i < j) crossed[fine_end++] = crossed[i++];
      } else {
        coarse.push_back(prefix);
      }
      i = j;
    }
    crossed.resize(fine_end);
    apply_sorted(*tree_, coarse, coarse_levels, tree_->getProbMissLog());
    apply_sorted(*tree_, crossed, 16, tree_->getProbMissLog());
  }
  if (tree_->size() > nodes_after_prune_ + nodes_after_prune_ / 4) {
    // Free space clamps to one value where it is seen often: collapse it (octomap's prune).
    tree_->prune();
    nodes_after_prune_ = tree_->size();
  }
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
  tree();
  write_checked(path, "OctoMap binary tree", [&](std::ostream& out) { return tree_->writeBinary(out); });
}

void write_color_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m) {
  octomap::ColorOcTree tree(resolution_m);
  for (const MapPoint& p : points) {
    if (!p.has_rgb) continue;
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(octomap::point3d(p.position_m.x(), p.position_m.y(), p.position_m.z()), key)) continue;
    // updateNode returns the leaf: no second search to colour it.
    tree.updateNode(key, true, /*lazy_eval=*/true)->setColor(p.rgb[0], p.rgb[1], p.rgb[2]);
  }
  // ColorOcTree's updateInnerOccupancy dereferences the root: an empty tree (no coloured
  // point) has none, and is written as a valid tree without nodes.
  if (tree.getRoot() != nullptr) tree.updateInnerOccupancy();
  write_checked(path, "OctoMap ColorOcTree", [&](std::ostream& out) { return tree.write(out); });
}

void write_thermal_octree(const std::string& path, const std::vector<MapPoint>& points, double resolution_m) {
  ThermalOcTree tree(resolution_m);
  for (const MapPoint& p : points) {
    if (std::isnan(p.temperature_k)) continue;
    octomap::OcTreeKey key;
    if (!tree.coordToKeyChecked(octomap::point3d(p.position_m.x(), p.position_m.y(), p.position_m.z()), key)) continue;
    tree.updateNode(key, true, /*lazy_eval=*/true)->set_temperature_k(p.temperature_k);
  }
  tree.update_inner_nodes();
  write_checked(path, "ThermalOcTree", [&](std::ostream& out) { return tree.write(out); });
}

}  // namespace rgbdt::rgbdt_map
