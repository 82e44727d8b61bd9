#include "rgbdt/cloud/pcd_io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "rgbdt/core/error.hpp"

namespace rgbdt::cloud {
namespace {

const pcl::PCLPointField* find_field(const pcl::PCLPointCloud2& msg,
                                     std::initializer_list<const char*> names) {
  for (const char* name : names) {
    for (const auto& f : msg.fields) {
      if (f.name == name) return &f;
    }
  }
  return nullptr;
}

double read_value(const std::uint8_t* p, const pcl::PCLPointField& f) {
  switch (f.datatype) {
    case pcl::PCLPointField::INT8: { std::int8_t v; std::memcpy(&v, p, 1); return v; }
    case pcl::PCLPointField::UINT8: { std::uint8_t v; std::memcpy(&v, p, 1); return v; }
    case pcl::PCLPointField::INT16: { std::int16_t v; std::memcpy(&v, p, 2); return v; }
    case pcl::PCLPointField::UINT16: { std::uint16_t v; std::memcpy(&v, p, 2); return v; }
    case pcl::PCLPointField::INT32: { std::int32_t v; std::memcpy(&v, p, 4); return v; }
    case pcl::PCLPointField::UINT32: { std::uint32_t v; std::memcpy(&v, p, 4); return v; }
    case pcl::PCLPointField::FLOAT32: { float v; std::memcpy(&v, p, 4); return v; }
    case pcl::PCLPointField::FLOAT64: { double v; std::memcpy(&v, p, 8); return v; }
    default: return std::nan("");
  }
}

}  // namespace

LoadedCloud load_pcd(const std::string& path) {
  if (!std::filesystem::exists(path)) throw core::Error(path, "point cloud file does not exist");
  pcl::PCLPointCloud2 msg;
  pcl::PCDReader reader;
  if (reader.read(path, msg) < 0) {
    throw core::Error(path, "cannot read as PCD (expected a PCD file with fields x y z)");
  }
  const auto* fx = find_field(msg, {"x"});
  const auto* fy = find_field(msg, {"y"});
  const auto* fz = find_field(msg, {"z"});
  if (!fx || !fy || !fz) {
    std::string fields;
    for (const auto& f : msg.fields) fields += (fields.empty() ? "" : " ") + f.name;
    throw core::Error(path, "PCD has fields '" + fields + "', expected at least x y z");
  }
  const auto* fi = find_field(msg, {"intensity", "i", "reflectivity"});
  const auto* fr = find_field(msg, {"ring", "line", "laser_id"});
  const auto* ft = find_field(msg, {"t", "time", "timestamp"});

  LoadedCloud out;
  out.has_intensity = fi != nullptr;
  out.has_ring = fr != nullptr;
  out.has_t = ft != nullptr;
  out.cloud.reset(new Cloud);
  const std::size_t n = static_cast<std::size_t>(msg.width) * msg.height;
  out.cloud->reserve(n);
  // Other tools store absolute times ("time", "timestamp"); ours is relative to the
  // cloud's first point, so subtract the earliest one (in double, before narrowing).
  double t0 = 0.0;
  if (ft && ft->name != "t" && n > 0) {
    t0 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
      const double v = read_value(msg.data.data() + i * msg.point_step + ft->offset, *ft);
      if (std::isfinite(v)) t0 = std::min(t0, v);
    }
    if (!std::isfinite(t0)) t0 = 0.0;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* base = msg.data.data() + i * msg.point_step;
    PointXYZIRT p;
    p.x = static_cast<float>(read_value(base + fx->offset, *fx));
    p.y = static_cast<float>(read_value(base + fy->offset, *fy));
    p.z = static_cast<float>(read_value(base + fz->offset, *fz));
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    if (fi) p.intensity = static_cast<float>(read_value(base + fi->offset, *fi));
    if (fr) p.ring = static_cast<std::uint16_t>(read_value(base + fr->offset, *fr));
    if (ft) p.t = static_cast<float>(read_value(base + ft->offset, *ft) - t0);
    out.cloud->push_back(p);
  }
  out.cloud->width = static_cast<std::uint32_t>(out.cloud->size());
  out.cloud->height = 1;
  out.cloud->is_dense = true;
  return out;
}

void save_pcd(const std::string& path, const Cloud& cloud, PcdFormat format) {
  if (cloud.empty()) {
    // PCL refuses to write empty clouds; an empty cloud is still a valid PCD.
    pcl::PCLPointCloud2 msg;
    Cloud one;
    one.push_back(PointXYZIRT{});
    pcl::toPCLPointCloud2(one, msg);
    msg.width = 0;
    msg.data.clear();
    pcl::PCDWriter writer;
    if (writer.writeASCII(path, msg) < 0) throw core::Error(path, "cannot write PCD");
    return;
  }
  pcl::PCDWriter writer;
  int rc = -1;
  try {
    switch (format) {
      case PcdFormat::kAscii: rc = writer.writeASCII(path, cloud, 9); break;
      case PcdFormat::kBinary: rc = writer.writeBinary(path, cloud); break;
      case PcdFormat::kBinaryCompressed: rc = writer.writeBinaryCompressed(path, cloud); break;
    }
  } catch (const std::exception& e) {
    throw core::Error(path, std::string("cannot write PCD: ") + e.what());
  }
  if (rc < 0) throw core::Error(path, "cannot write PCD (is the folder there and writable?)");
}

}  // namespace rgbdt::cloud
