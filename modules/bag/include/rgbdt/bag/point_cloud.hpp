#pragma once
/// \file
/// Points out of a sensor_msgs/PointCloud2 of any field layout: x, y, z, intensity, ring and
/// per-point time from the fields the common LIDAR drivers write.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/bag/messages.hpp"

namespace rgbdt::bag {

/// How a float64 `timestamp` field counts time. Livox (livox_ros_driver2) writes absolute
/// nanoseconds, Hesai and RoboSense absolute seconds; both use the same field name.
enum class TimestampUnit {
  kAuto,         ///< the unit that puts the cloud's first point nearer its header stamp
  kSeconds,      ///< Hesai, RoboSense
  kNanoseconds,  ///< Livox
};

struct PointExtractOptions {
  /// Change when a driver's clock differs from the header stamp's by so much that kAuto
  /// picks the wrong unit (an unsynchronised LIDAR counting from power-on).
  TimestampUnit float64_timestamp_unit = TimestampUnit::kAuto;
};

/// The points of one cloud in storage order (row by row), invalid (NaN) points included so
/// that indices match the message. Optional channels are empty when the cloud lacks them.
struct CloudPoints {
  std::vector<std::array<double, 3>> xyz;  ///< [m] in header.frame_id
  std::vector<float> intensity;            ///< from `intensity`, any numeric type
  std::vector<std::uint16_t> ring;  ///< from `ring` (Velodyne, Ouster, Hesai), `line` (Livox)
  /// Absolute time of each point [ns since epoch], from (first match wins):
  ///   `time`        float32/float64 seconds after header.stamp (Velodyne),
  ///   `t`           unsigned integer nanoseconds after header.stamp (Ouster), or float32/
  ///                 float64 seconds after header.stamp (rgbdt's own PCD field),
  ///   `offset_time` unsigned integer nanoseconds after header.stamp (Livox; float: seconds),
  ///   `timestamp`   float64 absolute, nanoseconds (Livox) or seconds (Hesai), see options.
  std::vector<std::int64_t> time_ns;
  std::string time_field;  ///< the field `time_ns` came from, empty when none
};

/// Extracts the points. x, y and z must be float32 or float64. Throws core::Error naming the
/// message (context) and the field when a field ends past point_step, a channel has an
/// unexpected datatype, row_step is smaller than width * point_step, or data holds fewer bytes
/// than the layout needs.
CloudPoints extract_points(const PointCloud2& cloud, const MessageContext& context,
                           const PointExtractOptions& options = {});

}  // namespace rgbdt::bag
