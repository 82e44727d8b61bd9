#include "rgbdt/bag/point_cloud.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "cdr.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

const char* datatype_name(std::uint8_t datatype) {
  switch (datatype) {
    case PointField::kInt8:
      return "INT8";
    case PointField::kUint8:
      return "UINT8";
    case PointField::kInt16:
      return "INT16";
    case PointField::kUint16:
      return "UINT16";
    case PointField::kInt32:
      return "INT32";
    case PointField::kUint32:
      return "UINT32";
    case PointField::kFloat32:
      return "FLOAT32";
    case PointField::kFloat64:
      return "FLOAT64";
    default:
      return "unknown";
  }
}

bool is_integer(std::uint8_t datatype) {
  return datatype >= PointField::kInt8 && datatype <= PointField::kUint32;
}
bool is_unsigned(std::uint8_t datatype) {
  return datatype == PointField::kUint8 || datatype == PointField::kUint16 ||
         datatype == PointField::kUint32;
}
bool is_float(std::uint8_t datatype) {
  return datatype == PointField::kFloat32 || datatype == PointField::kFloat64;
}

bool host_is_big_endian() {
  const std::uint16_t one = 1;
  std::uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

template <typename T>
T load(const std::uint8_t* p, bool swap) {
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if (swap) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

// The first element of a field as double; the datatype was checked by the caller.
double load_as_double(const std::uint8_t* p, std::uint8_t datatype, bool swap) {
  switch (datatype) {
    case PointField::kInt8:
      return load<std::int8_t>(p, swap);
    case PointField::kUint8:
      return load<std::uint8_t>(p, swap);
    case PointField::kInt16:
      return load<std::int16_t>(p, swap);
    case PointField::kUint16:
      return load<std::uint16_t>(p, swap);
    case PointField::kInt32:
      return load<std::int32_t>(p, swap);
    case PointField::kUint32:
      return load<std::uint32_t>(p, swap);
    case PointField::kFloat32:
      return load<float>(p, swap);
    default:
      return load<double>(p, swap);
  }
}

std::int64_t load_as_integer(const std::uint8_t* p, std::uint8_t datatype, bool swap) {
  switch (datatype) {
    case PointField::kInt8:
      return load<std::int8_t>(p, swap);
    case PointField::kUint8:
      return load<std::uint8_t>(p, swap);
    case PointField::kInt16:
      return load<std::int16_t>(p, swap);
    case PointField::kUint16:
      return load<std::uint16_t>(p, swap);
    case PointField::kInt32:
      return load<std::int32_t>(p, swap);
    default:
      return load<std::uint32_t>(p, swap);
  }
}

enum class TimeKind { kSecondsOffset, kNanosecondsOffset, kAbsoluteFloat64 };

class Extractor {
 public:
  Extractor(const PointCloud2& cloud, const MessageContext& context)
      : cloud_(cloud), context_(context) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw core::Error(detail::describe(context_), "sensor_msgs/msg/PointCloud2 " + what);
  }

  // Checks every field against point_step, and the data size against the layout.
  void check_layout() const {
    for (std::size_t i = 0; i < cloud_.fields.size(); ++i) {
      const PointField& f = cloud_.fields[i];
      const std::size_t size = point_field_size(f.datatype);
      if (size == 0) {
        fail("field '" + f.name + "' has datatype " + std::to_string(f.datatype) +
             ", expected 1..8 (INT8 .. FLOAT64)");
      }
      const std::uint64_t end =
          std::uint64_t{f.offset} + std::uint64_t{size} * std::max(f.count, 1u);
      if (end > cloud_.point_step) {
        fail("field '" + f.name + "' (offset " + std::to_string(f.offset) + ", " +
             std::to_string(std::max(f.count, 1u)) + " x " + datatype_name(f.datatype) +
             ") ends at byte " + std::to_string(end) + ", past point_step " +
             std::to_string(cloud_.point_step));
      }
    }
    const std::uint64_t row_bytes = std::uint64_t{cloud_.width} * cloud_.point_step;
    if (cloud_.height > 1 && cloud_.row_step < row_bytes) {
      fail("row_step " + std::to_string(cloud_.row_step) + " is less than width " +
           std::to_string(cloud_.width) + " x point_step " + std::to_string(cloud_.point_step));
    }
    const std::uint64_t size = cloud_.data.size();
    const std::string layout = "width " + std::to_string(cloud_.width) + " x height " +
                               std::to_string(cloud_.height) + " x point_step " +
                               std::to_string(cloud_.point_step);
    if (cloud_.height > 0 && row_bytes > size / cloud_.height) {
      fail("data has " + std::to_string(size) + " bytes, fewer than " + layout);
    }
    if (cloud_.height > 1 &&
        std::uint64_t{cloud_.height - 1} * cloud_.row_step > size - row_bytes) {
      fail("data has " + std::to_string(size) + " bytes, fewer than (height - 1) x row_step " +
           std::to_string(cloud_.row_step) + " + width x point_step for " + layout);
    }
  }

  const PointField* find(const char* name) const {
    for (const PointField& f : cloud_.fields) {
      if (f.name == name) return &f;
    }
    return nullptr;
  }

  const PointField& require_float(const char* name) const {
    const PointField* f = find(name);
    if (!f) fail("has no field '" + std::string(name) + "', expected x, y and z");
    if (!is_float(f->datatype)) {
      fail("field '" + std::string(name) + "' is " + datatype_name(f->datatype) +
           ", expected FLOAT32 or FLOAT64");
    }
    return *f;
  }

  const PointCloud2& cloud_;
  const MessageContext& context_;
};

}  // namespace

CloudPoints extract_points(const PointCloud2& cloud, const MessageContext& context,
                           const PointExtractOptions& options) {
  Extractor ex(cloud, context);
  ex.check_layout();
  const PointField& fx = ex.require_float("x");
  const PointField& fy = ex.require_float("y");
  const PointField& fz = ex.require_float("z");

  const PointField* intensity = ex.find("intensity");
  if (intensity && !is_integer(intensity->datatype) && !is_float(intensity->datatype)) {
    ex.fail("field 'intensity' has datatype " + std::to_string(intensity->datatype));
  }
  const PointField* ring = ex.find("ring");
  if (!ring) ring = ex.find("line");
  if (ring && !is_integer(ring->datatype)) {
    ex.fail("field '" + ring->name + "' is " + datatype_name(ring->datatype) +
            ", expected an integer type");
  }

  CloudPoints out;
  const PointField* time = nullptr;
  TimeKind time_kind = TimeKind::kSecondsOffset;
  if ((time = ex.find("time"))) {
    if (!is_float(time->datatype)) {
      ex.fail("field 'time' (Velodyne, seconds after the header stamp) is " +
              std::string(datatype_name(time->datatype)) + ", expected FLOAT32 or FLOAT64");
    }
    time_kind = TimeKind::kSecondsOffset;
  } else if ((time = ex.find("t")) || (time = ex.find("offset_time"))) {
    // Integers count nanoseconds (Ouster, Livox); floats seconds (rgbdt's own PCD `t`).
    if (is_float(time->datatype)) {
      time_kind = TimeKind::kSecondsOffset;
    } else if (is_unsigned(time->datatype)) {
      time_kind = TimeKind::kNanosecondsOffset;
    } else {
      ex.fail("field '" + time->name + "' (time after the header stamp) is " +
              datatype_name(time->datatype) +
              ", expected UINT8, UINT16 or UINT32 (nanoseconds) or FLOAT32 or FLOAT64 (seconds)");
    }
  } else if ((time = ex.find("timestamp"))) {
    if (time->datatype != PointField::kFloat64) {
      ex.fail("field 'timestamp' (absolute time) is " + std::string(datatype_name(time->datatype)) +
              ", expected FLOAT64");
    }
    time_kind = TimeKind::kAbsoluteFloat64;
  }
  if (time) out.time_field = time->name;

  const std::uint64_t n = std::uint64_t{cloud.width} * cloud.height;
  out.xyz.resize(n);
  if (intensity) out.intensity.resize(n);
  if (ring) out.ring.resize(n);
  if (time) out.time_ns.resize(n);
  // No points: done. (Walking the rows of a cloud of width 0 would cost up to 2^32 empty
  // iterations for a height the data size does not bound.)
  if (n == 0) return out;

  const bool swap = cloud.is_bigendian != host_is_big_endian();
  const std::int64_t stamp_ns = cloud.header.stamp.to_ns();
  // Unit of a float64 `timestamp`: nanoseconds = 1, seconds = 1e9; kAuto decides on the
  // first finite value.
  double timestamp_scale = options.float64_timestamp_unit == TimestampUnit::kSeconds ? 1e9 : 1.0;
  bool timestamp_unit_known = options.float64_timestamp_unit != TimestampUnit::kAuto;

  std::uint64_t i = 0;
  for (std::uint32_t row = 0; row < cloud.height; ++row) {
    const std::uint8_t* row_data = cloud.data.data() + std::uint64_t{row} * cloud.row_step;
    for (std::uint32_t col = 0; col < cloud.width; ++col, ++i) {
      const std::uint8_t* p = row_data + std::uint64_t{col} * cloud.point_step;
      out.xyz[i] = {load_as_double(p + fx.offset, fx.datatype, swap),
                    load_as_double(p + fy.offset, fy.datatype, swap),
                    load_as_double(p + fz.offset, fz.datatype, swap)};
      if (intensity) {
        out.intensity[i] =
            static_cast<float>(load_as_double(p + intensity->offset, intensity->datatype, swap));
      }
      if (ring) {
        const std::int64_t r = load_as_integer(p + ring->offset, ring->datatype, swap);
        if (r < 0 || r > std::numeric_limits<std::uint16_t>::max()) {
          ex.fail("point " + std::to_string(i) + " has " + ring->name + " " + std::to_string(r) +
                  ", expected 0..65535");
        }
        out.ring[i] = static_cast<std::uint16_t>(r);
      }
      if (!time) continue;
      if (time_kind == TimeKind::kNanosecondsOffset) {
        out.time_ns[i] = stamp_ns + load_as_integer(p + time->offset, time->datatype, swap);
        continue;
      }
      // Offsets are added to the stamp as integers: a double holds an absolute time only to
      // 256 ns.
      double t_ns = 0.0;
      std::int64_t base_ns = 0;
      if (time_kind == TimeKind::kSecondsOffset) {
        t_ns = load_as_double(p + time->offset, time->datatype, swap) * 1e9;
        base_ns = stamp_ns;
      } else {
        const double v = load<double>(p + time->offset, swap);
        if (!timestamp_unit_known && std::isfinite(v)) {
          const double as_ns = std::abs(v - double(stamp_ns));
          const double as_s = std::abs(v * 1e9 - double(stamp_ns));
          timestamp_scale = as_s < as_ns ? 1e9 : 1.0;
          timestamp_unit_known = true;
        }
        t_ns = v * timestamp_scale;
      }
      // 9.2e18 ns is the int64 limit (year 2262).
      if (!std::isfinite(t_ns) || std::abs(t_ns) > 9.2e18) {
        ex.fail("point " + std::to_string(i) + " has " + time->name +
                " that is not a finite time (" + std::to_string(t_ns) + " ns)");
      }
      // An offset near the limit added to the stamp can still leave the int64 range.
      std::int64_t sum = 0;
      if (__builtin_add_overflow(base_ns, std::llround(t_ns), &sum)) {
        ex.fail("point " + std::to_string(i) + " has " + time->name + " " + std::to_string(t_ns) +
                " ns after the header stamp " + std::to_string(base_ns) +
                " ns, past the int64 nanosecond range (year 2262)");
      }
      out.time_ns[i] = sum;
    }
  }
  return out;
}

}  // namespace rgbdt::bag
