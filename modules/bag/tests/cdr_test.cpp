// CDR decoding of the ROS 2 sensor messages: round trips through the test encoder (both byte
// orders) and hostile inputs, which must throw core::Error with a clear message and never read
// out of bounds or allocate from an unchecked length.
#include <gtest/gtest.h>

#include <functional>

#include "cdr_writer.hpp"
#include "rgbdt/bag/messages.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

const MessageContext kContext{"/sensors/test", 7, 1700000000123456789};

using Decoder = std::function<void(const std::vector<std::uint8_t>&)>;

void put_u32(std::vector<std::uint8_t>& bytes, std::size_t offset, std::uint32_t value) {
  std::memcpy(bytes.data() + offset, &value, 4);
}

std::string error_of(const Decoder& decode, const std::vector<std::uint8_t>& bytes) {
  try {
    decode(bytes);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "(no error)";
}

Image test_image() {
  Image image;
  image.header = {{1700000000, 5}, "thermal"};
  image.height = 2;
  image.width = 3;
  image.encoding = "mono16";
  image.step = 6;
  image.data = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  return image;
}

CameraInfo test_camera_info() {
  CameraInfo info;
  info.header = {{-3, 999999999}, "camera_optical"};
  info.height = 480;
  info.width = 640;
  info.distortion_model = "plumb_bob";
  info.d = {-0.25, 0.125, 0.001, -0.002, 0.03};
  info.k = {500, 0, 320, 0, 505, 240, 0, 0, 1};
  info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.p = {500, 0, 320, 0, 0, 505, 240, 0, 0, 0, 1, 0};
  info.binning_x = 2;
  info.binning_y = 3;
  info.roi = {10, 20, 30, 40, true};
  return info;
}

Imu test_imu() {
  Imu imu;
  imu.header = {{1700000001, 250000000}, "imu_link"};
  imu.orientation = {0.1, -0.2, 0.3, 0.9};
  imu.angular_velocity = {0.01, 0.02, -0.03};
  imu.linear_acceleration = {0.5, -0.25, 9.81};
  for (int i = 0; i < 9; ++i) {
    imu.orientation_covariance[i] = i;
    imu.angular_velocity_covariance[i] = 10 + i;
    imu.linear_acceleration_covariance[i] = 20 + i;
  }
  return imu;
}

class CdrByteOrder : public testing::TestWithParam<bool> {};

TEST_P(CdrByteOrder, PointCloud2RoundTrips) {
  const PointCloud2 cloud = test::velodyne_cloud(5, 1700000000, 123);
  const auto bytes = test::encode(cloud, GetParam());
  const PointCloud2 got = decode_point_cloud2(bytes.data(), bytes.size(), kContext);
  EXPECT_EQ(got.header.stamp.sec, 1700000000);
  EXPECT_EQ(got.header.stamp.nanosec, 123u);
  EXPECT_EQ(got.header.frame_id, "velodyne");
  EXPECT_EQ(got.height, 1u);
  EXPECT_EQ(got.width, 5u);
  ASSERT_EQ(got.fields.size(), 6u);
  for (std::size_t i = 0; i < got.fields.size(); ++i) {
    EXPECT_EQ(got.fields[i].name, cloud.fields[i].name);
    EXPECT_EQ(got.fields[i].offset, cloud.fields[i].offset);
    EXPECT_EQ(got.fields[i].datatype, cloud.fields[i].datatype);
    EXPECT_EQ(got.fields[i].count, 1u);
  }
  EXPECT_EQ(got.point_step, 32u);
  EXPECT_EQ(got.row_step, 160u);
  EXPECT_EQ(got.data, cloud.data);
  EXPECT_TRUE(got.is_dense);
  EXPECT_FALSE(got.is_bigendian);
}

TEST_P(CdrByteOrder, ImageAndCompressedImageRoundTrip) {
  const Image image = test_image();
  const auto bytes = test::encode(image, GetParam());
  const Image got = decode_image(bytes.data(), bytes.size(), kContext);
  EXPECT_EQ(got.header.stamp.to_ns(), 1700000000000000005);
  EXPECT_EQ(got.header.frame_id, "thermal");
  EXPECT_EQ(got.height, 2u);
  EXPECT_EQ(got.width, 3u);
  EXPECT_EQ(got.encoding, "mono16");
  EXPECT_EQ(got.step, 6u);
  EXPECT_EQ(got.data, image.data);

  CompressedImage jpeg;
  jpeg.header = {{42, 7}, ""};
  jpeg.format = "jpeg";
  jpeg.data = {0xff, 0xd8, 0xff, 0xe0, 0x00};
  const auto jpeg_bytes = test::encode(jpeg, GetParam());
  const CompressedImage got_jpeg =
      decode_compressed_image(jpeg_bytes.data(), jpeg_bytes.size(), kContext);
  EXPECT_EQ(got_jpeg.header.stamp.sec, 42);
  EXPECT_EQ(got_jpeg.header.frame_id, "");
  EXPECT_EQ(got_jpeg.format, "jpeg");
  EXPECT_EQ(got_jpeg.data, jpeg.data);
}

TEST_P(CdrByteOrder, CameraInfoRoundTrips) {
  const CameraInfo info = test_camera_info();
  const auto bytes = test::encode(info, GetParam());
  const CameraInfo got = decode_camera_info(bytes.data(), bytes.size(), kContext);
  EXPECT_EQ(got.header.stamp.sec, -3);
  EXPECT_EQ(got.header.stamp.nanosec, 999999999u);
  EXPECT_EQ(got.header.frame_id, "camera_optical");
  EXPECT_EQ(got.height, 480u);
  EXPECT_EQ(got.width, 640u);
  EXPECT_EQ(got.distortion_model, "plumb_bob");
  EXPECT_EQ(got.d, info.d);
  EXPECT_EQ(got.k, info.k);
  EXPECT_EQ(got.r, info.r);
  EXPECT_EQ(got.p, info.p);
  EXPECT_EQ(got.binning_x, 2u);
  EXPECT_EQ(got.binning_y, 3u);
  EXPECT_EQ(got.roi.x_offset, 10u);
  EXPECT_EQ(got.roi.y_offset, 20u);
  EXPECT_EQ(got.roi.height, 30u);
  EXPECT_EQ(got.roi.width, 40u);
  EXPECT_TRUE(got.roi.do_rectify);
}

TEST_P(CdrByteOrder, ImuRoundTrips) {
  const Imu imu = test_imu();
  const auto bytes = test::encode(imu, GetParam());
  const Imu got = decode_imu(bytes.data(), bytes.size(), kContext);
  EXPECT_EQ(got.header.stamp.to_ns(), 1700000001250000000);
  EXPECT_EQ(got.header.frame_id, "imu_link");
  EXPECT_EQ(got.orientation.x, 0.1);
  EXPECT_EQ(got.orientation.y, -0.2);
  EXPECT_EQ(got.orientation.z, 0.3);
  EXPECT_EQ(got.orientation.w, 0.9);
  EXPECT_EQ(got.angular_velocity.z, -0.03);
  EXPECT_EQ(got.linear_acceleration.z, 9.81);
  EXPECT_EQ(got.orientation_covariance, imu.orientation_covariance);
  EXPECT_EQ(got.angular_velocity_covariance, imu.angular_velocity_covariance);
  EXPECT_EQ(got.linear_acceleration_covariance, imu.linear_acceleration_covariance);
}

INSTANTIATE_TEST_SUITE_P(LittleAndBigEndian, CdrByteOrder, testing::Bool(),
                         [](const auto& info) { return info.param ? "Big" : "Little"; });

// Every strict prefix of a valid message lacks at least its last field.
TEST(CdrHostile, EveryTruncationThrows) {
  const std::vector<std::pair<std::string, std::pair<std::vector<std::uint8_t>, Decoder>>> cases = {
      {"PointCloud2",
       {test::encode(test::velodyne_cloud(3, 1, 2)),
        [](const auto& b) { decode_point_cloud2(b.data(), b.size(), kContext); }}},
      {"Image",
       {test::encode(test_image()),
        [](const auto& b) { decode_image(b.data(), b.size(), kContext); }}},
      {"CameraInfo",
       {test::encode(test_camera_info()),
        [](const auto& b) { decode_camera_info(b.data(), b.size(), kContext); }}},
      {"Imu", {test::encode(test_imu()), [](const auto& b) {
                 decode_imu(b.data(), b.size(), kContext);
               }}}};
  for (const auto& [name, bytes_and_decoder] : cases) {
    const auto& [bytes, decode] = bytes_and_decoder;
    ASSERT_NO_THROW(decode(bytes)) << name;
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      // A copy of exactly n bytes, so that ASan sees any read past the end.
      const std::vector<std::uint8_t> prefix(bytes.begin(), bytes.begin() + n);
      const std::string message = error_of(decode, prefix);
      EXPECT_NE(message, "(no error)") << name << " truncated to " << n << " bytes";
      EXPECT_NE(message.find("/sensors/test"), std::string::npos) << message;
    }
  }
}

TEST(CdrHostile, HugeSequenceLengthsThrowBeforeAllocating) {
  const auto valid = test::encode(test::velodyne_cloud(2, 1, 2));
  const Decoder decode = [](const auto& b) { decode_point_cloud2(b.data(), b.size(), kContext); };
  // Header: sec@4, nanosec@8, frame_id length@12 ("velodyne\0" = 9 bytes, to 25), pad to 28:
  // height@28, width@32, fields count@36, first field name length@40.
  auto bytes = valid;
  put_u32(bytes, 36, 0xFFFFFFFFu);
  std::string message = error_of(decode, bytes);
  EXPECT_NE(message.find("field fields"), std::string::npos) << message;
  EXPECT_NE(message.find("4294967295"), std::string::npos) << message;

  bytes = valid;
  put_u32(bytes, 12, 0xFFFFFFFFu);
  message = error_of(decode, bytes);
  EXPECT_NE(message.find("header.frame_id"), std::string::npos) << message;

  // The data length sits 4 + 64 bytes before the end (data, then is_dense).
  bytes = valid;
  put_u32(bytes, bytes.size() - 1 - 64 - 4, 0xFFFFFFFFu);
  message = error_of(decode, bytes);
  EXPECT_NE(message.find("field data"), std::string::npos) << message;

  auto info = test::encode(test_camera_info());
  // CameraInfo: frame_id "camera_optical\0" (15) from 16 to 31, pad to 32: height@32,
  // width@36, distortion_model length@40 ("plumb_bob\0" to 54), pad to 56: d count@56.
  put_u32(info, 56, 0xFFFFFFFFu);
  message = error_of([](const auto& b) { decode_camera_info(b.data(), b.size(), kContext); }, info);
  EXPECT_NE(message.find("field d"), std::string::npos) << message;
}

TEST(CdrHostile, StringWithoutNulThrows) {
  auto bytes = test::encode(test_image());
  // frame_id "thermal\0" occupies bytes 16..23.
  ASSERT_EQ(bytes[23], 0);
  bytes[23] = 'x';
  const std::string message =
      error_of([](const auto& b) { decode_image(b.data(), b.size(), kContext); }, bytes);
  EXPECT_NE(message.find("header.frame_id"), std::string::npos) << message;
  EXPECT_NE(message.find("NUL"), std::string::npos) << message;
}

TEST(CdrHostile, ErrorNamesTopicIndexTimeAndType) {
  const std::vector<std::uint8_t> bytes = {0x00, 0x01, 0x00, 0x00, 0x01};
  const std::string message =
      error_of([](const auto& b) { decode_imu(b.data(), b.size(), kContext); }, bytes);
  EXPECT_NE(message.find("topic /sensors/test"), std::string::npos) << message;
  EXPECT_NE(message.find("message 7"), std::string::npos) << message;
  EXPECT_NE(message.find("1700000000.123456789 s"), std::string::npos) << message;
  EXPECT_NE(message.find("sensor_msgs/msg/Imu field header.stamp.sec"), std::string::npos)
      << message;
}

TEST(CdrHostile, OtherEncapsulationsAreNamed) {
  auto bytes = test::encode(test_imu());
  bytes[1] = 0x03;  // PL_CDR_LE (parameter list)
  const std::string message =
      error_of([](const auto& b) { decode_imu(b.data(), b.size(), kContext); }, bytes);
  EXPECT_NE(message.find("{0x00,0x03}"), std::string::npos) << message;
}

TEST(CdrHostile, BoolOutsideZeroOneThrows) {
  auto bytes = test::encode(test::velodyne_cloud(1, 1, 2));
  bytes.back() = 7;  // is_dense
  const std::string message =
      error_of([](const auto& b) { decode_point_cloud2(b.data(), b.size(), kContext); }, bytes);
  EXPECT_NE(message.find("is_dense"), std::string::npos) << message;
}

TEST(Cdr, StdMsgsStringDecodes) {
  test::CdrWriter w;
  w.string("Hello, world! 3");
  const auto& b = w.bytes();
  EXPECT_EQ(decode_string(b.data(), b.size(), kContext), "Hello, world! 3");
}

}  // namespace
}  // namespace rgbdt::bag
