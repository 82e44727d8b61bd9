#include "rgbdt/rgbdt_map/voxel_map.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace rgbdt::rgbdt_map {
namespace {

// 21 bits per axis: +-2^20 voxels, i.e. +-52 km at 5 cm.
constexpr int kBits = 21;
constexpr std::int64_t kOffset = std::int64_t{1} << (kBits - 1);
constexpr std::uint64_t kMask = (std::uint64_t{1} << kBits) - 1;

}  // namespace

std::string VoxelMapOptions::validate() const {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    std::ostringstream os;
    os << "resolution_m = " << resolution_m << ", expected a positive number of metres";
    return os.str();
  }
  return {};
}

VoxelMap::VoxelMap(const VoxelMapOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("VoxelMapOptions: " + why);
  inv_resolution_ = static_cast<float>(1.0 / options.resolution_m);
}

int VoxelMap::add_thermal_layer(const std::string& name) {
  layer_names_.push_back(name);
  layers_.emplace_back();
  return static_cast<int>(layers_.size()) - 1;
}

const std::string& VoxelMap::thermal_layer_name(int layer) const {
  if (layer < 0 || layer >= thermal_layers()) {
    throw std::invalid_argument("VoxelMap: thermal layer " + std::to_string(layer) + " does not exist (have " +
                                std::to_string(thermal_layers()) + ")");
  }
  return layer_names_[layer];
}

const std::unordered_map<VoxelMap::Key, ThermalCell>& VoxelMap::thermal_layer(int layer) const {
  thermal_layer_name(layer);  // validates
  return layers_[layer];
}

VoxelMap::Key VoxelMap::key_of(const Eigen::Vector3f& p) const {
  Key key = 0;
  for (int a = 0; a < 3; ++a) {
    const std::int64_t i = static_cast<std::int64_t>(std::floor(p[a] * inv_resolution_)) + kOffset;
    key |= (static_cast<std::uint64_t>(i) & kMask) << (kBits * a);
  }
  return key;
}

void VoxelMap::insert(const std::vector<Eigen::Vector3f>& points, const RgbColors* rgb,
                      const Temperatures* temperatures, int thermal_layer, double time_s) {
  const std::size_t n = points.size();
  if (rgb && (rgb->rgb.size() != n || rgb->status.size() != n)) {
    throw std::invalid_argument("VoxelMap::insert: " + std::to_string(rgb->rgb.size()) + " colours for " +
                                std::to_string(n) + " points");
  }
  if (temperatures) {
    if (temperatures->temperature_k.size() != n || temperatures->status.size() != n) {
      throw std::invalid_argument("VoxelMap::insert: " + std::to_string(temperatures->temperature_k.size()) +
                                  " temperatures for " + std::to_string(n) + " points");
    }
    thermal_layer_name(thermal_layer);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite()) continue;
    const Key key = key_of(points[i]);
    Voxel& v = voxels_[key];
    ++v.count;
    // Running means: numerically stable and no sums to overflow on long sessions.
    v.mean_position_m += (points[i] - v.mean_position_m) / static_cast<float>(v.count);
    v.last_time_s = std::max(v.last_time_s, time_s);
    if (rgb && rgb->status[i] == ColorStatus::kColored) {
      ++v.color_count;
      const Eigen::Vector3f c(rgb->rgb[i][0], rgb->rgb[i][1], rgb->rgb[i][2]);
      v.mean_rgb += (c - v.mean_rgb) / static_cast<float>(v.color_count);
    }
    if (temperatures && temperatures->status[i] == ColorStatus::kColored) {
      ThermalCell& cell = layers_[thermal_layer][key];
      ++cell.count;
      cell.mean_k += (temperatures->temperature_k[i] - cell.mean_k) / static_cast<float>(cell.count);
    }
  }
}

std::vector<MapPoint> VoxelMap::points(int thermal_layer, std::uint32_t min_count) const {
  const std::unordered_map<Key, ThermalCell>* layer = nullptr;
  if (thermal_layer >= 0 && thermal_layer < thermal_layers()) layer = &layers_[thermal_layer];
  std::vector<MapPoint> out;
  out.reserve(voxels_.size());
  for (const auto& [key, v] : voxels_) {
    if (v.count < min_count) continue;
    MapPoint p;
    p.position_m = v.mean_position_m;
    p.has_rgb = v.color_count > 0;
    if (p.has_rgb) {
      for (int c = 0; c < 3; ++c) p.rgb[c] = static_cast<std::uint8_t>(std::lround(std::clamp(v.mean_rgb[c], 0.0f, 255.0f)));
    }
    p.temperature_k = std::numeric_limits<float>::quiet_NaN();
    if (layer) {
      const auto it = layer->find(key);
      if (it != layer->end()) p.temperature_k = it->second.mean_k;
    }
    p.count = v.count;
    p.last_time_s = v.last_time_s;
    out.push_back(p);
  }
  return out;
}

std::size_t VoxelMap::memory_bytes() const {
  // libstdc++ nodes: next pointer + key + value (+ cached hash), rounded to 16 bytes.
  auto node = [](std::size_t value) { return ((sizeof(void*) + sizeof(Key) + value + sizeof(std::size_t)) + 15) / 16 * 16; };
  std::size_t bytes = voxels_.size() * node(sizeof(Voxel)) + voxels_.bucket_count() * sizeof(void*);
  for (const auto& layer : layers_) bytes += layer.size() * node(sizeof(ThermalCell)) + layer.bucket_count() * sizeof(void*);
  return bytes;
}

}  // namespace rgbdt::rgbdt_map
