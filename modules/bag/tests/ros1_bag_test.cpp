// ROS 1 bags written by the real ROS 1 C++ library (rosbag::Bag with std_msgs and sensor_msgs
// from Debian), uncompressed and with bz2 and lz4 chunks, read back through open_bag.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>

#include <filesystem>

#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

namespace fs = std::filesystem;

template <typename Message>
std::vector<std::uint8_t> ros1_bytes(const Message& message) {
  std::vector<std::uint8_t> bytes(ros::serialization::serializationLength(message));
  ros::serialization::OStream stream(bytes.data(), static_cast<std::uint32_t>(bytes.size()));
  ros::serialization::serialize(stream, message);
  return bytes;
}

std_msgs::String chatter(int i) {
  std_msgs::String s;
  s.data = "hello " + std::to_string(i);
  return s;
}

sensor_msgs::PointCloud2 cloud(int i) {
  sensor_msgs::PointCloud2 c;
  c.header.seq = i;
  c.header.frame_id = "velodyne";
  c.height = 1;
  c.width = 3 + i;
  c.point_step = 12;
  c.row_step = 12 * c.width;
  for (const char* name : {"x", "y", "z"}) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = static_cast<std::uint32_t>(4 * c.fields.size());
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    c.fields.push_back(f);
  }
  c.data.assign(c.row_step, static_cast<std::uint8_t>(i));
  return c;
}

// 5 clouds at 10 Hz from t = 100 s, 10 chatter strings at 20 Hz from 100.01 s; clouds
// written first, so that the file order is not the time order.
fs::path write_bag(const std::string& name, rosbag::compression::CompressionType compression) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "bag" / "ros1";
  fs::create_directories(dir);
  const fs::path path = dir / name;
  rosbag::Bag bag(path.string(), rosbag::bagmode::Write);
  bag.setCompression(compression);
  bag.setChunkThreshold(512);  // several chunks
  for (int i = 0; i < 5; ++i) bag.write("/points", ros::Time(100, 100000000 * i), cloud(i));
  for (int i = 0; i < 10; ++i) {
    bag.write("/chatter", ros::Time(100, 10000000 + 50000000 * i), chatter(i));
  }
  bag.close();
  return path;
}

class Ros1Bag : public testing::TestWithParam<rosbag::compression::CompressionType> {};

TEST_P(Ros1Bag, ReadsTopicsAndMessageBytesInTimeOrder) {
  const fs::path path = write_bag("test_" + std::to_string(int(GetParam())) + ".bag", GetParam());
  const auto reader = open_bag(path);
  EXPECT_EQ(reader->storage_identifier(), "ros1");
  EXPECT_TRUE(reader->is_complete());
  ASSERT_EQ(reader->topics().size(), 2u);
  EXPECT_EQ(reader->topics()[0].name, "/chatter");
  EXPECT_EQ(reader->topics()[0].type, "std_msgs/String");
  EXPECT_EQ(reader->topics()[0].serialization_format, "ros1");
  EXPECT_EQ(reader->topics()[0].message_count, 10u);
  EXPECT_EQ(reader->topics()[1].name, "/points");
  EXPECT_EQ(reader->topics()[1].type, "sensor_msgs/PointCloud2");
  EXPECT_EQ(reader->topics()[1].message_count, 5u);

  int clouds = 0, strings = 0;
  std::int64_t last = 0;
  while (const auto message = reader->next()) {
    EXPECT_GE(message->log_time_ns, last);
    last = message->log_time_ns;
    const std::vector<std::uint8_t> bytes(message->data, message->data + message->size);
    if (message->topic->name == "/points") {
      EXPECT_EQ(message->log_time_ns, 100000000000 + 100000000 * clouds);
      EXPECT_EQ(bytes, ros1_bytes(cloud(clouds))) << "cloud " << clouds;
      ++clouds;
    } else {
      EXPECT_EQ(message->log_time_ns, 100010000000 + 50000000 * strings);
      EXPECT_EQ(bytes, ros1_bytes(chatter(strings))) << "string " << strings;
      ++strings;
    }
  }
  EXPECT_EQ(clouds, 5);
  EXPECT_EQ(strings, 10);
}

TEST_P(Ros1Bag, TopicAndTimeFiltersSelectMessages) {
  const fs::path path = write_bag("filter_" + std::to_string(int(GetParam())) + ".bag", GetParam());
  ReadOptions options;
  options.topics = {"/points"};
  options.start_ns = 100100000000;  // the second cloud
  options.end_ns = 100400000000;    // excluded: the fifth cloud
  const auto reader = open_bag(path, options);
  std::vector<std::int64_t> times;
  while (const auto message = reader->next()) {
    EXPECT_EQ(message->topic->name, "/points");
    times.push_back(message->log_time_ns);
  }
  EXPECT_EQ(times, (std::vector<std::int64_t>{100100000000, 100200000000, 100300000000}));
}

INSTANTIATE_TEST_SUITE_P(Compression, Ros1Bag,
                         testing::Values(rosbag::compression::Uncompressed,
                                         rosbag::compression::BZ2, rosbag::compression::LZ4),
                         [](const auto& info) {
                           switch (info.param) {
                             case rosbag::compression::BZ2:
                               return "Bz2";
                             case rosbag::compression::LZ4:
                               return "Lz4";
                             default:
                               return "Uncompressed";
                           }
                         });

TEST(Ros1BagDamaged, TruncatedBagThrowsCoreErrorNamingTheFile) {
  const fs::path path = write_bag("full.bag", rosbag::compression::Uncompressed);
  const fs::path cut = path.parent_path() / "cut.bag";
  fs::remove(cut);
  fs::copy_file(path, cut);
  fs::resize_file(cut, fs::file_size(path) / 2);
  try {
    const auto reader = open_bag(cut);
    while (reader->next()) {
    }
    FAIL() << "no error from a cut ROS 1 bag";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cut.bag"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rgbdt::bag
