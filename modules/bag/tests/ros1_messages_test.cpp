// ROS 1 decoding of the sensor messages: bytes serialized by the real ROS 1 C++ library
// (roscpp_serialization with Debian's sensor_msgs) decode to the same values, and damaged or
// hostile bytes throw core::Error naming the topic, never read out of bounds or allocate from
// an unchecked length.
#include <gtest/gtest.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>

#include <cstring>
#include <functional>

#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

const MessageContext kRos1{"/ros1/test", 4, 1700000000000000000, Serialization::kRos1};

template <typename Message>
std::vector<std::uint8_t> ros1_bytes(const Message& message) {
  std::vector<std::uint8_t> bytes(ros::serialization::serializationLength(message));
  ros::serialization::OStream stream(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  ros::serialization::serialize(stream, message);
  return bytes;
}

std_msgs::Header ros1_header(std::uint32_t seq, std::uint32_t sec, std::uint32_t nsec,
                             const std::string& frame) {
  std_msgs::Header h;
  h.seq = seq;
  h.stamp = ros::Time(sec, nsec);
  h.frame_id = frame;
  return h;
}

// 4 points of x y z (float32) intensity (float32) ring (uint16) time (float32), 22 bytes each
// (packed: ROS 1 drivers do not pad points).
sensor_msgs::PointCloud2 ros1_cloud() {
  sensor_msgs::PointCloud2 c;
  c.header = ros1_header(11, 1700000000, 500000000, "velodyne");
  c.height = 1;
  c.width = 4;
  const std::vector<std::pair<const char*, std::uint8_t>> fields = {
      {"x", sensor_msgs::PointField::FLOAT32},   {"y", sensor_msgs::PointField::FLOAT32},
      {"z", sensor_msgs::PointField::FLOAT32},   {"intensity", sensor_msgs::PointField::FLOAT32},
      {"ring", sensor_msgs::PointField::UINT16}, {"time", sensor_msgs::PointField::FLOAT32}};
  std::uint32_t offset = 0;
  for (const auto& [name, type] : fields) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = offset;
    f.datatype = type;
    f.count = 1;
    c.fields.push_back(f);
    offset += type == sensor_msgs::PointField::UINT16 ? 2 : 4;
  }
  c.point_step = offset;
  c.row_step = c.point_step * c.width;
  c.data.resize(c.row_step);
  for (std::uint32_t i = 0; i < c.width; ++i) {
    std::uint8_t* p = c.data.data() + i * c.point_step;
    const float xyzi[4] = {1.0f + i, -2.0f * i, 0.5f, 10.0f * i};
    const std::uint16_t ring = static_cast<std::uint16_t>(i % 2);
    const float time = 0.001f * i;
    std::memcpy(p, xyzi, 16);
    std::memcpy(p + 16, &ring, 2);
    std::memcpy(p + 18, &time, 4);
  }
  c.is_bigendian = false;
  c.is_dense = true;
  return c;
}

sensor_msgs::Image ros1_image() {
  sensor_msgs::Image image;
  image.header = ros1_header(3, 1700000001, 7, "camera");
  image.height = 2;
  image.width = 3;
  image.encoding = "rgb8";
  image.is_bigendian = 0;
  image.step = 9;
  for (int i = 0; i < 18; ++i) image.data.push_back(static_cast<std::uint8_t>(i * 13));
  return image;
}

sensor_msgs::CameraInfo ros1_camera_info() {
  sensor_msgs::CameraInfo info;
  info.header = ros1_header(0, 1700000002, 999999999, "camera_optical");
  info.height = 480;
  info.width = 640;
  info.distortion_model = "plumb_bob";
  info.D = {-0.25, 0.125, 0.001, -0.002, 0.03};
  info.K = {500, 0, 320, 0, 505, 240, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {500, 0, 320, 0, 0, 505, 240, 0, 0, 0, 1, 0};
  info.binning_x = 2;
  info.binning_y = 3;
  info.roi.x_offset = 10;
  info.roi.y_offset = 20;
  info.roi.height = 30;
  info.roi.width = 40;
  info.roi.do_rectify = true;
  return info;
}

sensor_msgs::Imu ros1_imu() {
  sensor_msgs::Imu imu;
  imu.header = ros1_header(99, 1700000003, 250000000, "imu_link");
  imu.orientation.x = 0.1;
  imu.orientation.y = -0.2;
  imu.orientation.z = 0.3;
  imu.orientation.w = 0.9;
  imu.angular_velocity.x = 0.01;
  imu.angular_velocity.y = 0.02;
  imu.angular_velocity.z = -0.03;
  imu.linear_acceleration.x = 0.5;
  imu.linear_acceleration.y = -0.25;
  imu.linear_acceleration.z = 9.81;
  for (int i = 0; i < 9; ++i) {
    imu.orientation_covariance[i] = i;
    imu.angular_velocity_covariance[i] = 10 + i;
    imu.linear_acceleration_covariance[i] = 20 + i;
  }
  return imu;
}

sensor_msgs::CompressedImage ros1_compressed() {
  sensor_msgs::CompressedImage image;
  image.header = ros1_header(5, 1700000004, 1, "camera");
  image.format = "jpeg";
  image.data = {0xff, 0xd8, 0xff, 0xe0, 0x00, 0x10};
  return image;
}

TEST(Ros1Messages, PointCloud2DecodesAsRoscppWroteIt) {
  const sensor_msgs::PointCloud2 original = ros1_cloud();
  const auto bytes = ros1_bytes(original);
  const PointCloud2 got = decode_point_cloud2(bytes.data(), bytes.size(), kRos1);
  EXPECT_EQ(got.header.seq, 11u);
  EXPECT_EQ(got.header.stamp.sec, 1700000000);
  EXPECT_EQ(got.header.stamp.nanosec, 500000000u);
  EXPECT_EQ(got.header.frame_id, "velodyne");
  EXPECT_EQ(got.height, 1u);
  EXPECT_EQ(got.width, 4u);
  ASSERT_EQ(got.fields.size(), 6u);
  EXPECT_EQ(got.fields[4].name, "ring");
  EXPECT_EQ(got.fields[4].offset, 16u);
  EXPECT_EQ(got.fields[4].datatype, PointField::kUint16);
  EXPECT_EQ(got.fields[5].count, 1u);
  EXPECT_EQ(got.point_step, 22u);
  EXPECT_EQ(got.row_step, 88u);
  EXPECT_EQ(got.data, original.data);
  EXPECT_TRUE(got.is_dense);
  EXPECT_FALSE(got.is_bigendian);

  const CloudPoints points = extract_points(got, kRos1);
  ASSERT_EQ(points.xyz.size(), 4u);
  EXPECT_EQ(points.xyz[3][0], 4.0);
  EXPECT_EQ(points.xyz[3][1], -6.0);
  EXPECT_EQ(points.ring, (std::vector<std::uint16_t>{0, 1, 0, 1}));
  EXPECT_EQ(points.time_field, "time");
  // float32 0.003 s after the stamp: within float precision (~1e-10 s) of 3 ms.
  EXPECT_NEAR(double(points.time_ns[3] - got.header.stamp.to_ns()), 3e6, 1.0);
}

TEST(Ros1Messages, ImageDecodesAsRoscppWroteIt) {
  const sensor_msgs::Image original = ros1_image();
  const auto bytes = ros1_bytes(original);
  const Image got = decode_image(bytes.data(), bytes.size(), kRos1);
  EXPECT_EQ(got.header.seq, 3u);
  EXPECT_EQ(got.header.stamp.to_ns(), 1700000001000000007);
  EXPECT_EQ(got.header.frame_id, "camera");
  EXPECT_EQ(got.height, 2u);
  EXPECT_EQ(got.width, 3u);
  EXPECT_EQ(got.encoding, "rgb8");
  EXPECT_EQ(got.step, 9u);
  EXPECT_EQ(got.data, original.data);
}

TEST(Ros1Messages, CompressedImageDecodesAsRoscppWroteIt) {
  const auto original = ros1_compressed();
  const auto bytes = ros1_bytes(original);
  const CompressedImage got = decode_compressed_image(bytes.data(), bytes.size(), kRos1);
  EXPECT_EQ(got.header.frame_id, "camera");
  EXPECT_EQ(got.format, "jpeg");
  EXPECT_EQ(got.data, original.data);
}

TEST(Ros1Messages, CameraInfoDecodesAsRoscppWroteIt) {
  const auto original = ros1_camera_info();
  const auto bytes = ros1_bytes(original);
  const CameraInfo got = decode_camera_info(bytes.data(), bytes.size(), kRos1);
  EXPECT_EQ(got.header.stamp.to_ns(), 1700000002999999999);
  EXPECT_EQ(got.header.frame_id, "camera_optical");
  EXPECT_EQ(got.width, 640u);
  EXPECT_EQ(got.height, 480u);
  EXPECT_EQ(got.distortion_model, "plumb_bob");
  EXPECT_EQ(got.d, original.D);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(got.k[i], original.K[i]) << i;
  for (int i = 0; i < 9; ++i) EXPECT_EQ(got.r[i], original.R[i]) << i;
  for (int i = 0; i < 12; ++i) EXPECT_EQ(got.p[i], original.P[i]) << i;
  EXPECT_EQ(got.binning_x, 2u);
  EXPECT_EQ(got.binning_y, 3u);
  EXPECT_EQ(got.roi.x_offset, 10u);
  EXPECT_EQ(got.roi.width, 40u);
  EXPECT_TRUE(got.roi.do_rectify);
}

TEST(Ros1Messages, ImuDecodesAsRoscppWroteIt) {
  const auto original = ros1_imu();
  const auto bytes = ros1_bytes(original);
  const Imu got = decode_imu(bytes.data(), bytes.size(), kRos1);
  EXPECT_EQ(got.header.seq, 99u);
  EXPECT_EQ(got.header.frame_id, "imu_link");
  EXPECT_EQ(got.orientation.w, 0.9);
  EXPECT_EQ(got.angular_velocity.z, -0.03);
  EXPECT_EQ(got.linear_acceleration.z, 9.81);
  EXPECT_EQ(got.orientation_covariance[8], 8.0);
  EXPECT_EQ(got.angular_velocity_covariance[0], 10.0);
  EXPECT_EQ(got.linear_acceleration_covariance[4], 24.0);
}

using Decoder = std::function<void(const std::uint8_t*, std::size_t)>;

struct Case {
  const char* type;
  std::vector<std::uint8_t> bytes;
  Decoder decode;
};

std::vector<Case> all_cases() {
  return {
      {"sensor_msgs/PointCloud2", ros1_bytes(ros1_cloud()),
       [](const std::uint8_t* d, std::size_t n) { decode_point_cloud2(d, n, kRos1); }},
      {"sensor_msgs/Image", ros1_bytes(ros1_image()),
       [](const std::uint8_t* d, std::size_t n) { decode_image(d, n, kRos1); }},
      {"sensor_msgs/CompressedImage", ros1_bytes(ros1_compressed()),
       [](const std::uint8_t* d, std::size_t n) { decode_compressed_image(d, n, kRos1); }},
      {"sensor_msgs/CameraInfo", ros1_bytes(ros1_camera_info()),
       [](const std::uint8_t* d, std::size_t n) { decode_camera_info(d, n, kRos1); }},
      {"sensor_msgs/Imu", ros1_bytes(ros1_imu()),
       [](const std::uint8_t* d, std::size_t n) { decode_imu(d, n, kRos1); }},
  };
}

// Every proper prefix of a message is truncated: each must throw core::Error naming the
// topic and the ROS 1 type. The prefix is copied into a buffer of exactly its size so that
// ASan catches any read past it.
TEST(Ros1Messages, EveryTruncationThrowsNamingTopicAndType) {
  for (const Case& c : all_cases()) {
    for (std::size_t n = 0; n < c.bytes.size(); ++n) {
      const std::unique_ptr<std::uint8_t[]> cut(new std::uint8_t[n > 0 ? n : 1]);
      std::memcpy(cut.get(), c.bytes.data(), n);
      try {
        c.decode(cut.get(), n);
        ADD_FAILURE() << c.type << " cut to " << n << " of " << c.bytes.size()
                      << " bytes decoded without error";
      } catch (const core::Error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("/ros1/test"), std::string::npos) << what;
        EXPECT_NE(what.find(c.type), std::string::npos) << what;
      }
    }
  }
}

// A length prefix of 4 billion must fail on the check against the bytes left, not try the
// allocation: every uint32 in the message is set to 0xFFFFFFFF in turn.
TEST(Ros1Messages, HugeLengthsThrowWithoutAllocating) {
  for (const Case& c : all_cases()) {
    for (std::size_t offset = 0; offset + 4 <= c.bytes.size(); ++offset) {
      std::vector<std::uint8_t> bytes = c.bytes;
      const std::uint32_t huge = 0xFFFFFFFF;
      std::memcpy(bytes.data() + offset, &huge, 4);
      try {
        c.decode(bytes.data(), bytes.size());
      } catch (const core::Error& e) {
        EXPECT_NE(std::string(e.what()).find("/ros1/test"), std::string::npos) << e.what();
      }
    }
  }
}

TEST(Ros1Messages, TimeAfter2038IsAnErrorNamingTheField) {
  sensor_msgs::Image image = ros1_image();
  image.header.stamp = ros::Time(0x80000000u, 0);
  const auto bytes = ros1_bytes(image);
  try {
    decode_image(bytes.data(), bytes.size(), kRos1);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("header.stamp.secs"), std::string::npos) << e.what();
  }
}

TEST(Ros1Messages, BoolOtherThanZeroOrOneIsAnError) {
  auto bytes = ros1_bytes(ros1_cloud());
  bytes.back() = 7;  // is_dense
  try {
    decode_point_cloud2(bytes.data(), bytes.size(), kRos1);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("is_dense"), std::string::npos) << e.what();
  }
}

TEST(Ros1Messages, ContextTakesTheSerializationFromTheTopic) {
  TopicInfo ros1{"/a", "sensor_msgs/Image", "ros1", 1};
  TopicInfo cdr{"/b", "sensor_msgs/msg/Image", "cdr", 1};
  TopicInfo json{"/c", "foo/Bar", "json", 1};
  BagMessage message;
  message.topic = &ros1;
  EXPECT_EQ(context_of(message).serialization, Serialization::kRos1);
  message.topic = &cdr;
  EXPECT_EQ(context_of(message).serialization, Serialization::kCdr);
  message.topic = &json;
  try {
    context_of(message);
    FAIL() << "no error for serialization format json";
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/c"), std::string::npos) << what;
    EXPECT_NE(what.find("json"), std::string::npos) << what;
    EXPECT_NE(what.find("foo/Bar"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace rgbdt::bag
