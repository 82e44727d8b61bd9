#pragma once
/// \file
/// ROS sensor messages as plain structs, decoded from their serialized bytes: CDR for ROS 2 (as
/// stored in MCAP and sqlite3 bags) and the ROS 1 serialization (as stored in ROS 1 bags).
/// Field names follow the ROS 2 .msg definitions.
///
/// Decoding checks every length against the bytes left before allocating, so a damaged or
/// hostile message costs at most its own size. Failures throw rgbdt::core::Error whose
/// message names the topic, the message's index and log time, the field and what was
/// expected.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rgbdt::bag {

struct BagMessage;
struct TopicInfo;

/// How a message's bytes are laid out.
enum class Serialization {
  /// ROS 2 (TopicInfo::serialization_format "cdr"): a 4-byte encapsulation header, then plain
  /// CDR (XCDR1), little or big endian, primitives aligned to their size, strings with a NUL.
  kCdr,
  /// ROS 1 (serialization_format "ros1"): little endian, packed (no alignment), strings and
  /// sequences with a uint32 length prefix and no NUL, std_msgs/Header with a leading `seq`.
  kRos1,
};

/// Where a message came from, for error messages, and how it is serialized. Fill from a
/// BagMessage with `context_of`.
struct MessageContext {
  std::string topic;             ///< topic name, or a description such as a file name
  std::uint64_t index = 0;       ///< the message's index in its reader
  std::int64_t log_time_ns = 0;  ///< [ns since epoch]
  Serialization serialization = Serialization::kCdr;
};

/// The serialization of a topic, from its serialization_format ("cdr" or "ros1"). Throws
/// core::Error naming the topic, its type and the format when it is neither.
Serialization serialization_of(const TopicInfo& topic);

/// The context of a message; its serialization comes from its topic (serialization_of, which
/// throws for a format the decoders cannot read).
MessageContext context_of(const BagMessage& message);

/// builtin_interfaces/msg/Time.
struct Time {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  std::int64_t to_ns() const { return std::int64_t{sec} * 1000000000 + nanosec; }  ///< [ns]
};

/// std_msgs/msg/Header.
struct Header {
  Time stamp;
  std::string frame_id;
  std::uint32_t seq = 0;  ///< ROS 1 only: the publisher's sequence number; 0 for ROS 2
};

/// sensor_msgs/msg/PointField.
struct PointField {
  enum Datatype : std::uint8_t {
    kInt8 = 1,
    kUint8 = 2,
    kInt16 = 3,
    kUint16 = 4,
    kInt32 = 5,
    kUint32 = 6,
    kFloat32 = 7,
    kFloat64 = 8,
  };
  std::string name;
  std::uint32_t offset = 0;   ///< [bytes] from the start of a point
  std::uint8_t datatype = 0;  ///< one of Datatype
  std::uint32_t count = 1;    ///< elements of `datatype` in the field
};

/// Bytes of one element of `datatype`, or 0 for a value outside PointField::Datatype.
std::size_t point_field_size(std::uint8_t datatype);

/// sensor_msgs/msg/PointCloud2.
struct PointCloud2 {
  Header header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::vector<PointField> fields;
  bool is_bigendian = false;
  std::uint32_t point_step = 0;  ///< [bytes] per point
  std::uint32_t row_step = 0;    ///< [bytes] per row
  std::vector<std::uint8_t> data;
  bool is_dense = false;
};

/// sensor_msgs/msg/Image.
struct Image {
  Header header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::string encoding;  ///< e.g. "mono8", "rgb8", "bayer_rggb8"
  std::uint8_t is_bigendian = 0;
  std::uint32_t step = 0;  ///< [bytes] per row
  std::vector<std::uint8_t> data;
};

/// sensor_msgs/msg/CompressedImage.
struct CompressedImage {
  Header header;
  std::string format;  ///< e.g. "jpeg", "png", "rgb8; jpeg compressed bgr8"
  std::vector<std::uint8_t> data;
};

/// sensor_msgs/msg/RegionOfInterest.
struct RegionOfInterest {
  std::uint32_t x_offset = 0;
  std::uint32_t y_offset = 0;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  bool do_rectify = false;
};

/// sensor_msgs/msg/CameraInfo (ROS 2 field names: d, k, r, p).
struct CameraInfo {
  Header header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::string distortion_model;  ///< e.g. "plumb_bob", "equidistant"
  std::vector<double> d;
  std::array<double, 9> k{};   ///< row-major 3x3 intrinsics
  std::array<double, 9> r{};   ///< row-major 3x3 rectification
  std::array<double, 12> p{};  ///< row-major 3x4 projection
  std::uint32_t binning_x = 0;
  std::uint32_t binning_y = 0;
  RegionOfInterest roi;
};

/// geometry_msgs/msg/Vector3.
struct Vector3 {
  double x = 0, y = 0, z = 0;
};

/// geometry_msgs/msg/Quaternion.
struct Quaternion {
  double x = 0, y = 0, z = 0, w = 1;
};

/// sensor_msgs/msg/Imu.
struct Imu {
  Header header;
  Quaternion orientation;
  std::array<double, 9> orientation_covariance{};  ///< row-major; [0] = -1 when unknown
  Vector3 angular_velocity;                        ///< [rad/s]
  std::array<double, 9> angular_velocity_covariance{};
  Vector3 linear_acceleration;  ///< [m/s^2]
  std::array<double, 9> linear_acceleration_covariance{};
};

// Decoders of a whole message in context.serialization. CDR: the 4-byte encapsulation header,
// then the fields, plain CDR (XCDR1), little or big endian, as every ROS 2 middleware writes by
// default; other encapsulations are rejected by name; bytes after the last field are ignored
// (the DDS serializers pad to 4 bytes). ROS 1: the fields packed, little endian; a ROS 1 time
// after 2038 (seconds above INT32_MAX) does not fit Time and is an error. The types are the
// same in both: ROS 1's CameraInfo D, K, R, P are d, k, r, p here.

PointCloud2 decode_point_cloud2(const std::uint8_t* data, std::size_t size,
                                const MessageContext& context);
Image decode_image(const std::uint8_t* data, std::size_t size, const MessageContext& context);
CompressedImage decode_compressed_image(const std::uint8_t* data, std::size_t size,
                                        const MessageContext& context);
CameraInfo decode_camera_info(const std::uint8_t* data, std::size_t size,
                              const MessageContext& context);
Imu decode_imu(const std::uint8_t* data, std::size_t size, const MessageContext& context);
/// std_msgs/msg/String: its `data` field.
std::string decode_string(const std::uint8_t* data, std::size_t size,
                          const MessageContext& context);

}  // namespace rgbdt::bag
