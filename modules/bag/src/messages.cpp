#include "rgbdt/bag/messages.hpp"

#include "cdr.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {

using detail::MessageReader;

Serialization serialization_of(const TopicInfo& topic) {
  if (topic.serialization_format == "cdr") return Serialization::kCdr;
  if (topic.serialization_format == "ros1") return Serialization::kRos1;
  throw core::Error("topic " + topic.name,
                    "type " + topic.type + " has serialization format '" +
                        topic.serialization_format +
                        "', expected cdr (ROS 2) or ros1 (ROS 1): the messages cannot be decoded");
}

MessageContext context_of(const BagMessage& message) {
  MessageContext context;
  context.topic = message.topic ? message.topic->name : std::string("(unknown topic)");
  context.index = message.index;
  context.log_time_ns = message.log_time_ns;
  if (message.topic) context.serialization = serialization_of(*message.topic);
  return context;
}

std::size_t point_field_size(std::uint8_t datatype) {
  switch (datatype) {
    case PointField::kInt8:
    case PointField::kUint8:
      return 1;
    case PointField::kInt16:
    case PointField::kUint16:
      return 2;
    case PointField::kInt32:
    case PointField::kUint32:
    case PointField::kFloat32:
      return 4;
    case PointField::kFloat64:
      return 8;
    default:
      return 0;
  }
}

PointCloud2 decode_point_cloud2(const std::uint8_t* data, std::size_t size,
                                const MessageContext& context) {
  MessageReader in(data, size, context, "sensor_msgs/msg/PointCloud2");
  PointCloud2 cloud;
  cloud.header = in.header("header");
  cloud.height = in.u32("height");
  cloud.width = in.u32("width");
  // A PointField takes at least 4 (name length) + 4 + 1 + 4 bytes: 13 packed (ROS 1), 16
  // with CDR's alignment.
  const std::uint32_t n_fields = in.sequence_length(in.is_ros1() ? 13 : 16, "fields");
  cloud.fields.resize(n_fields);
  for (std::uint32_t i = 0; i < n_fields; ++i) {
    const std::string f = "fields[" + std::to_string(i) + "]";
    PointField& field = cloud.fields[i];
    field.name = in.string(f + ".name");
    field.offset = in.u32(f + ".offset");
    field.datatype = in.u8(f + ".datatype");
    field.count = in.u32(f + ".count");
  }
  cloud.is_bigendian = in.boolean("is_bigendian");
  cloud.point_step = in.u32("point_step");
  cloud.row_step = in.u32("row_step");
  cloud.data = in.bytes("data");
  cloud.is_dense = in.boolean("is_dense");
  return cloud;
}

Image decode_image(const std::uint8_t* data, std::size_t size, const MessageContext& context) {
  MessageReader in(data, size, context, "sensor_msgs/msg/Image");
  Image image;
  image.header = in.header("header");
  image.height = in.u32("height");
  image.width = in.u32("width");
  image.encoding = in.string("encoding");
  image.is_bigendian = in.u8("is_bigendian");
  image.step = in.u32("step");
  image.data = in.bytes("data");
  return image;
}

CompressedImage decode_compressed_image(const std::uint8_t* data, std::size_t size,
                                        const MessageContext& context) {
  MessageReader in(data, size, context, "sensor_msgs/msg/CompressedImage");
  CompressedImage image;
  image.header = in.header("header");
  image.format = in.string("format");
  image.data = in.bytes("data");
  return image;
}

CameraInfo decode_camera_info(const std::uint8_t* data, std::size_t size,
                              const MessageContext& context) {
  MessageReader in(data, size, context, "sensor_msgs/msg/CameraInfo");
  CameraInfo info;
  info.header = in.header("header");
  info.height = in.u32("height");
  info.width = in.u32("width");
  info.distortion_model = in.string("distortion_model");
  info.d = in.doubles("d");
  in.doubles(info.k.data(), info.k.size(), "k");
  in.doubles(info.r.data(), info.r.size(), "r");
  in.doubles(info.p.data(), info.p.size(), "p");
  info.binning_x = in.u32("binning_x");
  info.binning_y = in.u32("binning_y");
  info.roi.x_offset = in.u32("roi.x_offset");
  info.roi.y_offset = in.u32("roi.y_offset");
  info.roi.height = in.u32("roi.height");
  info.roi.width = in.u32("roi.width");
  info.roi.do_rectify = in.boolean("roi.do_rectify");
  return info;
}

Imu decode_imu(const std::uint8_t* data, std::size_t size, const MessageContext& context) {
  MessageReader in(data, size, context, "sensor_msgs/msg/Imu");
  Imu imu;
  imu.header = in.header("header");
  imu.orientation.x = in.f64("orientation.x");
  imu.orientation.y = in.f64("orientation.y");
  imu.orientation.z = in.f64("orientation.z");
  imu.orientation.w = in.f64("orientation.w");
  in.doubles(imu.orientation_covariance.data(), 9, "orientation_covariance");
  imu.angular_velocity.x = in.f64("angular_velocity.x");
  imu.angular_velocity.y = in.f64("angular_velocity.y");
  imu.angular_velocity.z = in.f64("angular_velocity.z");
  in.doubles(imu.angular_velocity_covariance.data(), 9, "angular_velocity_covariance");
  imu.linear_acceleration.x = in.f64("linear_acceleration.x");
  imu.linear_acceleration.y = in.f64("linear_acceleration.y");
  imu.linear_acceleration.z = in.f64("linear_acceleration.z");
  in.doubles(imu.linear_acceleration_covariance.data(), 9, "linear_acceleration_covariance");
  return imu;
}

std::string decode_string(const std::uint8_t* data, std::size_t size,
                          const MessageContext& context) {
  MessageReader in(data, size, context, "std_msgs/msg/String");
  return in.string("data");
}

}  // namespace rgbdt::bag
