#pragma once
// The bodies of the bag fuzz targets, shared by the libFuzzer programs and by the gtest that
// replays the regression corpus (tests/fuzz_corpus_test.cpp). Unreadable input must end in
// rgbdt::core::Error; any other exception, a crash, a broken invariant (std::abort) or an
// allocation far beyond the input's size is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <unistd.h>

#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag::fuzz {

/// The message types message_input decodes, picked by bits 1..3 of the first byte (modulo 6).
enum class MessageType { kPointCloud2, kImage, kCompressedImage, kCameraInfo, kImu, kString };
constexpr int kMessageTypes = 6;

/// The first byte of a message_input: bit 0 the serialization (0 CDR, 1 ROS 1), bits 1..3 the
/// type, bits 4..7 (modulo 3) the float64 timestamp unit extract_points is given.
inline std::uint8_t message_selector(Serialization serialization, MessageType type,
                                     int timestamp_unit = 0) {
  return static_cast<std::uint8_t>((serialization == Serialization::kRos1 ? 1 : 0) |
                                   (static_cast<int>(type) << 1) | (timestamp_unit << 4));
}

namespace detail {

// Decodes one message of `type`; returns 1, or 2 for a PointCloud2 whose points were also
// extracted. Throws core::Error for a message the decoders refuse.
inline int decode(MessageType type, const std::uint8_t* data, std::size_t size,
                  const MessageContext& context, const PointExtractOptions& options) {
  // Nothing decoded may hold more elements than the message had bytes.
  auto bounded = [size](std::size_t elements, std::size_t min_bytes) {
    if (elements > size / min_bytes) std::abort();
  };
  switch (type) {
    case MessageType::kPointCloud2: {
      const PointCloud2 cloud = decode_point_cloud2(data, size, context);
      bounded(cloud.fields.size(), 13);
      bounded(cloud.data.size(), 1);
      const CloudPoints points = extract_points(cloud, context, options);
      const std::uint64_t n = std::uint64_t{cloud.width} * cloud.height;
      // x, y and z take at least 4 bytes each per point, and the data holds every point.
      if (n > 0 && n > cloud.data.size() / 4) std::abort();
      if (points.xyz.size() != n) std::abort();
      if (!points.intensity.empty() && points.intensity.size() != n) std::abort();
      if (!points.ring.empty() && points.ring.size() != n) std::abort();
      if (!points.time_ns.empty() && points.time_ns.size() != n) std::abort();
      if (points.time_field.empty() != points.time_ns.empty() && n > 0) std::abort();
      return 2;
    }
    case MessageType::kImage: {
      const Image image = decode_image(data, size, context);
      bounded(image.data.size() + image.encoding.size() + image.header.frame_id.size(), 1);
      return 1;
    }
    case MessageType::kCompressedImage: {
      const CompressedImage image = decode_compressed_image(data, size, context);
      bounded(image.data.size() + image.format.size() + image.header.frame_id.size(), 1);
      return 1;
    }
    case MessageType::kCameraInfo: {
      const CameraInfo info = decode_camera_info(data, size, context);
      bounded(info.d.size(), sizeof(double));
      return 1;
    }
    case MessageType::kImu:
      decode_imu(data, size, context);
      return 1;
    case MessageType::kString:
      bounded(decode_string(data, size, context).size(), 1);
      return 1;
  }
  std::abort();
}

// The message type of a ROS type name in ROS 2 ("sensor_msgs/msg/Image") or ROS 1
// ("sensor_msgs/Image") form; false for the others.
inline bool type_of(const std::string& name, MessageType& type) {
  static const struct {
    const char* ros2;
    const char* ros1;
    MessageType type;
  } kTypes[] = {
      {"sensor_msgs/msg/PointCloud2", "sensor_msgs/PointCloud2", MessageType::kPointCloud2},
      {"sensor_msgs/msg/Image", "sensor_msgs/Image", MessageType::kImage},
      {"sensor_msgs/msg/CompressedImage", "sensor_msgs/CompressedImage",
       MessageType::kCompressedImage},
      {"sensor_msgs/msg/CameraInfo", "sensor_msgs/CameraInfo", MessageType::kCameraInfo},
      {"sensor_msgs/msg/Imu", "sensor_msgs/Imu", MessageType::kImu},
      {"std_msgs/msg/String", "std_msgs/String", MessageType::kString},
  };
  for (const auto& t : kTypes) {
    if (name == t.ros2 || name == t.ros1) {
      type = t.type;
      return true;
    }
  }
  return false;
}

}  // namespace detail

/// Arbitrary bytes as one serialized message: the first byte picks the serialization, the type
/// and the timestamp unit (message_selector), the rest is decoded, and a PointCloud2's points
/// extracted. Returns 0 when the message is refused (core::Error), 1 when it decodes, 2 when a
/// PointCloud2 decodes and its points extract.
inline int message_input(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  MessageContext context;
  context.topic = "/fuzz";
  context.index = 7;
  context.log_time_ns = 1700000000123456789;
  context.serialization = (data[0] & 1) ? Serialization::kRos1 : Serialization::kCdr;
  const auto type = static_cast<MessageType>(((data[0] >> 1) & 7) % kMessageTypes);
  PointExtractOptions options;
  options.float64_timestamp_unit = static_cast<TimestampUnit>((data[0] >> 4) % 3);
  try {
    return detail::decode(type, data + 1, size - 1, context, options);
  } catch (const core::Error& e) {
    // Every decoder error names the message.
    if (std::string(e.what()).find("topic /fuzz, message 7") == std::string::npos) std::abort();
    return 0;
  }
}

/// Messages mcap_input reads at most; a file that holds more is not read further.
constexpr int kMaxBagMessages = 4096;

/// Arbitrary bytes as a bag file (open_bag tells MCAP, sqlite3 and ROS 1 apart by the magic;
/// the fuzzer is built without the ROS 1 reader): open it, read every message and decode the
/// ones of a known type. Returns the messages read, or -1 when opening or reading threw
/// core::Error, which must name the file.
inline int mcap_input(const std::uint8_t* data, std::size_t size) {
  // open_bag reads files only, so the bytes go to a per-process temporary file.
  static const std::string path = "/tmp/rgbdt_bag_fuzz_" + std::to_string(::getpid()) + ".mcap";
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) std::abort();
    if (size && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
  }
  int messages = 0;
  try {
    const auto reader = open_bag(path);
    const auto& topics = reader->topics();
    while (messages < kMaxBagMessages) {
      const auto message = reader->next();
      if (!message) break;
      if (message->index != static_cast<std::uint64_t>(messages)) std::abort();
      ++messages;
      if (!message->topic || message->topic < topics.data() ||
          message->topic >= topics.data() + topics.size()) {
        std::abort();  // must point into topics()
      }
      if (message->size > 0 && !message->data) std::abort();
      MessageType type;
      if (!detail::type_of(message->topic->type, type)) continue;
      try {
        detail::decode(type, message->data, message->size, context_of(*message), {});
      } catch (const core::Error&) {
      }
    }
  } catch (const core::Error& e) {
    if (std::string(e.what()).find(path) == std::string::npos) std::abort();  // must name the file
    messages = -1;
  }
  std::remove(path.c_str());
  return messages;
}

}  // namespace rgbdt::bag::fuzz
