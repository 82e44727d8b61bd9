// MCAP files written by the mcap library's own McapWriter (zstd, lz4 and uncompressed chunks),
// read back through open_bag and decoded.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <zstd.h>

#include <mcap/reader.hpp>
#include <mcap/writer.hpp>

#include <filesystem>
#include <fstream>

#include "cdr_writer.hpp"
#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kT0 = 1700000000000000000;  // [ns]

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "bag" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

struct Written {
  std::int64_t log_time_ns;
  std::string topic;
  std::vector<std::uint8_t> bytes;
};

// Writes `messages` in the given order (not necessarily time order) into an MCAP file.
void write_mcap(const fs::path& path, mcap::Compression compression,
                const std::vector<Written>& messages) {
  mcap::McapWriterOptions options("ros2");
  options.compression = compression;
  options.forceCompression = true;  // compressed chunks even where it would not pay
  options.chunkSize = 2048;         // several chunks
  mcap::McapWriter writer;
  const mcap::Status status = writer.open(path.string(), options);
  ASSERT_TRUE(status.ok()) << status.message;
  // The definitions are abridged: the reader does not use them. (An empty one would make the
  // writer fwrite from a null pointer, which UBSan flags.)
  mcap::Schema cloud_schema("sensor_msgs/msg/PointCloud2", "ros2msg",
                            "std_msgs/Header header\nuint32 height\nuint32 width\n...");
  mcap::Schema imu_schema("sensor_msgs/msg/Imu", "ros2msg",
                          "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n...");
  writer.addSchema(cloud_schema);
  writer.addSchema(imu_schema);
  mcap::Channel cloud_channel("/points", "cdr", cloud_schema.id);
  mcap::Channel imu_channel("/imu", "cdr", imu_schema.id);
  writer.addChannel(cloud_channel);
  writer.addChannel(imu_channel);
  for (const Written& w : messages) {
    mcap::Message m;
    m.channelId = w.topic == "/points" ? cloud_channel.id : imu_channel.id;
    m.sequence = 0;
    m.logTime = static_cast<mcap::Timestamp>(w.log_time_ns);
    m.publishTime = m.logTime;
    m.data = reinterpret_cast<const std::byte*>(w.bytes.data());
    m.dataSize = w.bytes.size();
    const mcap::Status written = writer.write(m);
    ASSERT_TRUE(written.ok()) << written.message;
  }
  writer.close();
}

// 4 clouds at 10 Hz (cloud k has 50 + k points) and 20 IMU samples at 50 Hz, listed clouds
// first, so that time order differs from the order written.
std::vector<Written> sensor_messages(std::int64_t t0) {
  std::vector<Written> out;
  for (int k = 0; k < 4; ++k) {
    const std::int64_t t = t0 + k * 100000000;
    out.push_back({t, "/points",
                   test::encode(test::velodyne_cloud(50 + k, std::int32_t(t / 1000000000),
                                                     std::uint32_t(t % 1000000000)))});
  }
  for (int k = 0; k < 20; ++k) {
    Imu imu;
    const std::int64_t t = t0 + k * 20000000 + 1;
    imu.header.stamp = {std::int32_t(t / 1000000000), std::uint32_t(t % 1000000000)};
    imu.linear_acceleration.z = 9.8 + 0.001 * k;
    out.push_back({t, "/imu", test::encode(imu)});
  }
  return out;
}

class McapRoundTrip : public testing::TestWithParam<mcap::Compression> {
 protected:
  // A folder per compression: ctest runs the instances as parallel processes.
  fs::path param_dir(const std::string& name) const {
    return temp_dir(name + "_" + std::to_string(static_cast<int>(GetParam())));
  }
};

TEST_P(McapRoundTrip, ReadsBackInTimeOrderAndDecodes) {
  const fs::path file = param_dir("roundtrip") / "sensors.mcap";
  const auto messages = sensor_messages(kT0);
  write_mcap(file, GetParam(), messages);

  const auto reader = open_bag(file);
  EXPECT_EQ(reader->storage_identifier(), "mcap");
  ASSERT_EQ(reader->topics().size(), 2u);
  EXPECT_EQ(reader->topics()[0].name, "/imu");  // sorted by name
  EXPECT_EQ(reader->topics()[0].type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(reader->topics()[0].serialization_format, "cdr");
  EXPECT_EQ(reader->topics()[0].message_count, 20u);
  EXPECT_EQ(reader->topics()[1].name, "/points");
  EXPECT_EQ(reader->topics()[1].type, "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(reader->topics()[1].message_count, 4u);

  std::int64_t last = 0;
  int clouds = 0, imus = 0;
  while (const auto message = reader->next()) {
    EXPECT_GE(message->log_time_ns, last);
    last = message->log_time_ns;
    const MessageContext context = context_of(*message);
    if (message->topic->name == "/points") {
      const PointCloud2 cloud = decode_point_cloud2(message->data, message->size, context);
      EXPECT_EQ(cloud.header.stamp.to_ns(), message->log_time_ns);
      EXPECT_EQ(cloud.width, 50u + clouds);
      const PointCloud2 want = test::velodyne_cloud(50 + clouds, 0, 0);
      EXPECT_EQ(cloud.data, want.data);
      const CloudPoints points = extract_points(cloud, context);
      EXPECT_EQ(points.xyz.back()[0], double(49 + clouds));
      EXPECT_EQ(points.time_ns.front(), message->log_time_ns);
      ++clouds;
    } else {
      const Imu imu = decode_imu(message->data, message->size, context);
      EXPECT_EQ(imu.header.stamp.to_ns(), message->log_time_ns);
      EXPECT_EQ(imu.linear_acceleration.z, 9.8 + 0.001 * imus);
      ++imus;
    }
  }
  EXPECT_EQ(clouds, 4);
  EXPECT_EQ(imus, 20);
  EXPECT_EQ(last, kT0 + 19 * 20000000 + 1);
}

TEST_P(McapRoundTrip, TopicFilterReadsOnlyThatTopic) {
  const fs::path file = param_dir("filter") / "sensors.mcap";
  write_mcap(file, GetParam(), sensor_messages(kT0));
  ReadOptions options;
  options.topics = {"/points"};
  options.start_ns = kT0 + 100000000;  // drops the first cloud
  const auto reader = open_bag(file, options);
  std::vector<std::int64_t> times;
  while (const auto message = reader->next()) {
    EXPECT_EQ(message->topic->name, "/points");
    times.push_back(message->log_time_ns);
  }
  EXPECT_EQ(times, (std::vector<std::int64_t>{kT0 + 100000000, kT0 + 200000000, kT0 + 300000000}));
}

INSTANTIATE_TEST_SUITE_P(Compression, McapRoundTrip,
                         testing::Values(mcap::Compression::Zstd, mcap::Compression::Lz4,
                                         mcap::Compression::None),
                         [](const auto& info) {
                           switch (info.param) {
                             case mcap::Compression::Zstd:
                               return "Zstd";
                             case mcap::Compression::Lz4:
                               return "Lz4";
                             default:
                               return "None";
                           }
                         });

// A split bag: two files whose times interleave, in a folder without metadata.yaml.
TEST(McapFolder, MergesFilesInTimeOrder) {
  const fs::path dir = temp_dir("split");
  write_mcap(dir / "bag_0.mcap", mcap::Compression::Zstd, sensor_messages(kT0));
  write_mcap(dir / "bag_1.mcap", mcap::Compression::Lz4, sensor_messages(kT0 + 50000000));
  const auto reader = open_bag(dir);
  ASSERT_EQ(reader->topics().size(), 2u);
  EXPECT_EQ(reader->topics()[0].message_count, 40u);
  EXPECT_EQ(reader->topics()[1].message_count, 8u);
  std::int64_t last = 0;
  std::uint64_t n = 0;
  std::vector<std::int64_t> cloud_times;
  while (const auto message = reader->next()) {
    EXPECT_GE(message->log_time_ns, last);
    last = message->log_time_ns;
    if (message->topic->name == "/points") {
      // Each message's bytes stay valid until the next call: decode it now.
      const PointCloud2 cloud =
          decode_point_cloud2(message->data, message->size, context_of(*message));
      EXPECT_EQ(cloud.header.stamp.to_ns(), message->log_time_ns);
      cloud_times.push_back(message->log_time_ns);
    }
    ++n;
  }
  EXPECT_EQ(n, 48u);
  ASSERT_EQ(cloud_times.size(), 8u);
  EXPECT_EQ(cloud_times[1], kT0 + 50000000);  // from the second file
  EXPECT_EQ(cloud_times[2], kT0 + 100000000);
}

TEST(McapDamaged, CutFileReadsUpToTheCutAndSaysSo) {
  const fs::path dir = temp_dir("cut");
  write_mcap(dir / "full.mcap", mcap::Compression::Zstd, sensor_messages(kT0));
  EXPECT_TRUE(open_bag(dir / "full.mcap")->is_complete());
  // Cut inside the data section, as a killed recorder leaves it: no summary, no footer.
  const auto size = fs::file_size(dir / "full.mcap");
  fs::copy_file(dir / "full.mcap", dir / "cut.mcap");
  fs::resize_file(dir / "cut.mcap", size / 2);
  const auto reader = open_bag(dir / "cut.mcap");
  EXPECT_FALSE(reader->is_complete());
  std::uint64_t counted = 0;
  for (const TopicInfo& topic : reader->topics()) counted += topic.message_count;
  std::uint64_t n = 0;
  while (const auto message = reader->next()) {
    if (message->topic->name == "/imu")
      decode_imu(message->data, message->size, context_of(*message));
    ++n;
  }
  EXPECT_GT(n, 0u);
  EXPECT_LT(n, 24u);
  EXPECT_EQ(n, counted);
}

TEST(McapDamaged, CorruptChunkThrowsCoreErrorNamingTheFile) {
  const fs::path dir = temp_dir("corrupt");
  const fs::path file = dir / "corrupt.mcap";
  write_mcap(file, mcap::Compression::Zstd, sensor_messages(kT0));
  // Break the first chunk's zstd frame magic; the summary stays intact. (The mcap library
  // does not check the chunk CRCs, so damage inside a frame would pass as message bytes; the
  // message decoders bound what such bytes can do.)
  {
    std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const std::size_t frame = bytes.find("\x28\xb5\x2f\xfd");
    ASSERT_NE(frame, std::string::npos);
    f.seekp(std::streamoff(frame));
    f.write("\x5a\x5a\x5a\x5a", 4);
  }
  try {
    const auto reader = open_bag(file);
    std::uint64_t n = 0;
    while (reader->next()) ++n;
    FAIL() << "read " << n << " messages from a corrupt file without an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt.mcap: MCAP file is damaged"), std::string::npos)
        << e.what();
  }
}

long peak_rss_mb() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024;
}

// The vendored library's own guard (its "rgbdt patch" in decompressAll): a chunk that states
// more uncompressed bytes than its data can make is refused before the library allocates them.
// open_bag checks every Chunk record it knows the library will read first; this holds for any
// path that check misses. 1.5 GB stated for 1 kB: without the guard the peak RSS grows by it.
TEST(McapLibrary, ChunkStatingMoreThanItsDataCanMakeIsRefusedBeforeAllocating) {
  const std::uint64_t stated = 1536ull << 20;
  const long before = peak_rss_mb();

  const std::vector<std::byte> lz4_data(1024, std::byte{0x5a});
  mcap::LZ4Reader lz4;
  lz4.reset(lz4_data.data(), lz4_data.size(), stated);
  EXPECT_FALSE(lz4.status().ok());
  EXPECT_NE(lz4.status().message.find("more than 255 times"), std::string::npos)
      << lz4.status().message;
  EXPECT_EQ(lz4.size(), 0u);

  // A real zstd frame of 1000 bytes, stated as 1.5 GB.
  const std::string plain(1000, 'x');
  std::vector<std::byte> frame(ZSTD_compressBound(plain.size()));
  const std::size_t n = ZSTD_compress(frame.data(), frame.size(), plain.data(), plain.size(), 3);
  ASSERT_FALSE(ZSTD_isError(n));
  frame.resize(n);
  mcap::ZStdReader zstd;
  zstd.reset(frame.data(), frame.size(), stated);
  EXPECT_FALSE(zstd.status().ok());
  EXPECT_NE(zstd.status().message.find("not the size its frame declares"), std::string::npos)
      << zstd.status().message;
  EXPECT_EQ(zstd.size(), 0u);

  EXPECT_LT(peak_rss_mb() - before, 256) << "MB allocated for chunks that were refused";

  // The same frame stated truthfully decompresses.
  zstd.reset(frame.data(), frame.size(), plain.size());
  ASSERT_TRUE(zstd.status().ok()) << zstd.status().message;
  std::byte* out = nullptr;
  ASSERT_EQ(zstd.read(&out, 0, plain.size()), plain.size());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(out), plain.size()), plain);
}

}  // namespace
}  // namespace rgbdt::bag
