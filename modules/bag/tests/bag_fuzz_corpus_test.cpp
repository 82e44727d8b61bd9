// Replays the libFuzzer corpora of the bag readers (modules/bag/fuzz/corpus/{message,mcap})
// through the same target bodies, so every input that once mattered is checked in every build:
// the valid seeds decode, the findings are refused with core::Error, nothing crashes.
//
// The generated seeds come from DISABLED_WriteSeeds (the test CDR writer, a packed ROS 1 writer
// below and the mcap library's McapWriter); rewrite them with
//   bag_fuzz_corpus_test --gtest_also_run_disabled_tests --gtest_filter='*WriteSeeds'
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <mcap/writer.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <vector>

#include "../fuzz/targets.hpp"
#include "cdr_writer.hpp"

namespace rgbdt::bag {
namespace {

namespace fs = std::filesystem;
using fuzz::MessageType;
using Bytes = std::vector<std::uint8_t>;

fs::path corpus_dir(const std::string& name) {
  return fs::path(RGBDT_SOURCE_DIR) / "modules/bag/fuzz/corpus" / name;
}

std::map<std::string, Bytes> corpus(const std::string& name) {
  const fs::path dir = corpus_dir(name);
  std::map<std::string, Bytes> out;
  if (!fs::exists(dir)) return out;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename() == "NOTICE") continue;
    std::ifstream in(e.path(), std::ios::binary);
    out[e.path().filename().string()] = {std::istreambuf_iterator<char>(in), {}};
  }
  return out;
}

// ROS 1 serialization, written from its rules independently of the decoder: little endian,
// packed, strings and sequences as uint32 length + elements (no NUL), Header with `seq`.
class Ros1Writer {
 public:
  template <typename T>
  void put(T value) {
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));  // the tests run on little-endian hosts
    bytes_.insert(bytes_.end(), raw, raw + sizeof(T));
  }
  void string(const std::string& s) {
    put(static_cast<std::uint32_t>(s.size()));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  void byte_sequence(const Bytes& data) {
    put(static_cast<std::uint32_t>(data.size()));
    bytes_.insert(bytes_.end(), data.begin(), data.end());
  }
  void header(const Header& h) {
    put(h.seq);
    put(static_cast<std::uint32_t>(h.stamp.sec));
    put(h.stamp.nanosec);
    string(h.frame_id);
  }
  const Bytes& bytes() const { return bytes_; }

 private:
  Bytes bytes_;
};

Bytes ros1(const PointCloud2& m) {
  Ros1Writer w;
  w.header(m.header);
  w.put(m.height);
  w.put(m.width);
  w.put(static_cast<std::uint32_t>(m.fields.size()));
  for (const PointField& f : m.fields) {
    w.string(f.name);
    w.put(f.offset);
    w.put(f.datatype);
    w.put(f.count);
  }
  w.put(static_cast<std::uint8_t>(m.is_bigendian));
  w.put(m.point_step);
  w.put(m.row_step);
  w.byte_sequence(m.data);
  w.put(static_cast<std::uint8_t>(m.is_dense));
  return w.bytes();
}
Bytes ros1(const Image& m) {
  Ros1Writer w;
  w.header(m.header);
  w.put(m.height);
  w.put(m.width);
  w.string(m.encoding);
  w.put(m.is_bigendian);
  w.put(m.step);
  w.byte_sequence(m.data);
  return w.bytes();
}
Bytes ros1(const CompressedImage& m) {
  Ros1Writer w;
  w.header(m.header);
  w.string(m.format);
  w.byte_sequence(m.data);
  return w.bytes();
}
Bytes ros1(const CameraInfo& m) {
  Ros1Writer w;
  w.header(m.header);
  w.put(m.height);
  w.put(m.width);
  w.string(m.distortion_model);
  w.put(static_cast<std::uint32_t>(m.d.size()));
  for (double v : m.d) w.put(v);
  for (double v : m.k) w.put(v);
  for (double v : m.r) w.put(v);
  for (double v : m.p) w.put(v);
  for (std::uint32_t v :
       {m.binning_x, m.binning_y, m.roi.x_offset, m.roi.y_offset, m.roi.height, m.roi.width}) {
    w.put(v);
  }
  w.put(static_cast<std::uint8_t>(m.roi.do_rectify));
  return w.bytes();
}
Bytes ros1(const Imu& m) {
  Ros1Writer w;
  w.header(m.header);
  for (double v : {m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w}) w.put(v);
  for (double v : m.orientation_covariance) w.put(v);
  for (double v : {m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z}) w.put(v);
  for (double v : m.angular_velocity_covariance) w.put(v);
  for (double v : {m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z}) {
    w.put(v);
  }
  for (double v : m.linear_acceleration_covariance) w.put(v);
  return w.bytes();
}
Bytes ros1_string(const std::string& s) {
  Ros1Writer w;
  w.string(s);
  return w.bytes();
}
Bytes cdr_string(const std::string& s) {
  test::CdrWriter w;
  w.string(s);
  return w.bytes();
}

// Small messages of every type, with sensible values.
Header header(const char* frame) {
  Header h;
  h.stamp = {1700000000, 123456789};
  h.frame_id = frame;
  h.seq = 42;
  return h;
}
Image image() {
  Image m;
  m.header = header("camera");
  m.height = 2;
  m.width = 4;
  m.encoding = "mono8";
  m.step = 4;
  m.data = {0, 32, 64, 96, 128, 160, 192, 255};
  return m;
}
CompressedImage compressed_image() {
  CompressedImage m;
  m.header = header("camera");
  m.format = "png";
  m.data = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return m;
}
CameraInfo camera_info() {
  CameraInfo m;
  m.header = header("camera");
  m.height = 480;
  m.width = 640;
  m.distortion_model = "plumb_bob";
  m.d = {-0.1, 0.01, 0.001, -0.002, 0.0};
  m.k = {500, 0, 320, 0, 500, 240, 0, 0, 1};
  m.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.p = {500, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0};
  m.roi.width = 640;
  m.roi.height = 480;
  return m;
}
Imu imu() {
  Imu m;
  m.header = header("imu");
  m.orientation = {0, 0, 0.7071067811865476, 0.7071067811865476};
  m.angular_velocity = {0.01, -0.02, 0.03};
  m.linear_acceleration = {0.1, 0.2, 9.81};
  m.orientation_covariance[0] = -1;
  return m;
}
// An Ouster-like cloud: float32 x y z, uint16 ring, uint32 `t` nanoseconds; 2 rows of 3.
PointCloud2 ouster_cloud() {
  PointCloud2 m;
  m.header = header("os_lidar");
  m.height = 2;
  m.width = 3;
  m.fields = {{"x", 0, PointField::kFloat32, 1},
              {"y", 4, PointField::kFloat32, 1},
              {"z", 8, PointField::kFloat32, 1},
              {"ring", 12, PointField::kUint16, 1},
              {"t", 16, PointField::kUint32, 1}};
  m.point_step = 20;
  m.row_step = 64;  // padded rows
  m.data.assign(128, 0);
  for (std::uint32_t i = 0; i < 6; ++i) {
    std::uint8_t* p = m.data.data() + (i / 3) * 64 + (i % 3) * 20;
    const float xyz[3] = {float(i), 1.0f, -0.5f};
    std::memcpy(p, xyz, sizeof(xyz));
    const std::uint16_t ring = static_cast<std::uint16_t>(i / 3);
    std::memcpy(p + 12, &ring, 2);
    const std::uint32_t t = 1000 * i;
    std::memcpy(p + 16, &t, 4);
  }
  m.is_dense = true;
  return m;
}
// A Livox/Hesai-like cloud: float64 x y z, float32 intensity, uint8 line, float64 absolute
// `timestamp` in seconds.
PointCloud2 hesai_cloud() {
  PointCloud2 m;
  m.header = header("hesai");
  m.height = 1;
  m.width = 4;
  m.fields = {{"x", 0, PointField::kFloat64, 1},   {"y", 8, PointField::kFloat64, 1},
              {"z", 16, PointField::kFloat64, 1},  {"intensity", 24, PointField::kFloat32, 1},
              {"line", 28, PointField::kUint8, 1}, {"timestamp", 32, PointField::kFloat64, 1}};
  m.point_step = 40;
  m.row_step = 160;
  m.data.assign(160, 0);
  for (std::uint32_t i = 0; i < 4; ++i) {
    std::uint8_t* p = m.data.data() + i * 40;
    const double xyz[3] = {0.5 * i, -1.0, 2.0};
    std::memcpy(p, xyz, sizeof(xyz));
    const float intensity = 10.0f * float(i);
    std::memcpy(p + 24, &intensity, 4);
    p[28] = static_cast<std::uint8_t>(i);
    const double t = 1700000000.123 + 1e-5 * i;
    std::memcpy(p + 32, &t, 8);
  }
  return m;
}

Bytes with_selector(Serialization s, MessageType type, const Bytes& message, int unit = 0) {
  Bytes out(message.size() + 1);
  out[0] = fuzz::message_selector(s, type, unit);
  std::copy(message.begin(), message.end(), out.begin() + 1);
  return out;
}

// The generated message seeds, by file name.
std::map<std::string, Bytes> message_seeds() {
  constexpr auto kCdr = Serialization::kCdr;
  constexpr auto kRos1 = Serialization::kRos1;
  std::map<std::string, Bytes> out;
  const PointCloud2 velodyne = test::velodyne_cloud(4, 1700000000, 5000);
  out["valid_cloud_velodyne_cdr"] =
      with_selector(kCdr, MessageType::kPointCloud2, test::encode(velodyne));
  out["valid_cloud_velodyne_cdr_be"] =
      with_selector(kCdr, MessageType::kPointCloud2, test::encode(velodyne, true));
  out["valid_cloud_velodyne_ros1"] =
      with_selector(kRos1, MessageType::kPointCloud2, ros1(velodyne));
  out["valid_cloud_ouster_cdr"] =
      with_selector(kCdr, MessageType::kPointCloud2, test::encode(ouster_cloud()));
  out["valid_cloud_ouster_ros1"] =
      with_selector(kRos1, MessageType::kPointCloud2, ros1(ouster_cloud()));
  out["valid_cloud_hesai_cdr_auto"] =
      with_selector(kCdr, MessageType::kPointCloud2, test::encode(hesai_cloud()), 0);
  out["valid_cloud_hesai_ros1_seconds"] =
      with_selector(kRos1, MessageType::kPointCloud2, ros1(hesai_cloud()), 1);
  out["valid_image_cdr"] = with_selector(kCdr, MessageType::kImage, test::encode(image()));
  out["valid_image_cdr_be"] = with_selector(kCdr, MessageType::kImage, test::encode(image(), true));
  out["valid_image_ros1"] = with_selector(kRos1, MessageType::kImage, ros1(image()));
  out["valid_compressed_image_cdr"] =
      with_selector(kCdr, MessageType::kCompressedImage, test::encode(compressed_image()));
  out["valid_compressed_image_ros1"] =
      with_selector(kRos1, MessageType::kCompressedImage, ros1(compressed_image()));
  out["valid_camera_info_cdr"] =
      with_selector(kCdr, MessageType::kCameraInfo, test::encode(camera_info()));
  out["valid_camera_info_ros1"] =
      with_selector(kRos1, MessageType::kCameraInfo, ros1(camera_info()));
  out["valid_imu_cdr"] = with_selector(kCdr, MessageType::kImu, test::encode(imu()));
  out["valid_imu_cdr_be"] = with_selector(kCdr, MessageType::kImu, test::encode(imu(), true));
  out["valid_imu_ros1"] = with_selector(kRos1, MessageType::kImu, ros1(imu()));
  out["valid_string_cdr"] = with_selector(kCdr, MessageType::kString, cdr_string("hello, bag"));
  out["valid_string_ros1"] = with_selector(kRos1, MessageType::kString, ros1_string("hello, bag"));
  return out;
}

// One MCAP file of every decoded type (2 clouds, 2 IMU samples, an image, a compressed image,
// a camera info, a string) in chunks of `compression`; `chunk_size` 0 writes no chunks.
void write_sensor_mcap(const fs::path& path, mcap::Compression compression,
                       std::uint64_t chunk_size) {
  mcap::McapWriterOptions options("ros2");
  options.compression = compression;
  options.forceCompression = compression != mcap::Compression::None;
  options.chunkSize = chunk_size;
  options.noChunking = chunk_size == 0;
  mcap::McapWriter writer;
  const mcap::Status status = writer.open(path.string(), options);
  ASSERT_TRUE(status.ok()) << status.message;
  struct Topic {
    const char* name;
    const char* type;
    mcap::ChannelId channel = 0;
  };
  Topic topics[] = {{"/points", "sensor_msgs/msg/PointCloud2"},
                    {"/imu", "sensor_msgs/msg/Imu"},
                    {"/image", "sensor_msgs/msg/Image"},
                    {"/image/compressed", "sensor_msgs/msg/CompressedImage"},
                    {"/camera_info", "sensor_msgs/msg/CameraInfo"},
                    {"/chatter", "std_msgs/msg/String"}};
  for (Topic& t : topics) {
    // An abridged definition: the reader does not use it (and an empty one would make the
    // writer fwrite from a null pointer).
    mcap::Schema schema(t.type, "ros2msg", "# abridged");
    writer.addSchema(schema);
    mcap::Channel channel(t.name, "cdr", schema.id);
    writer.addChannel(channel);
    t.channel = channel.id;
  }
  const std::int64_t t0 = 1700000000000000000;
  const std::vector<std::pair<int, Bytes>> messages = {
      {0, test::encode(test::velodyne_cloud(3, 1700000000, 0))},
      {1, test::encode(imu())},
      {2, test::encode(image())},
      {3, test::encode(compressed_image())},
      {4, test::encode(camera_info())},
      {5, cdr_string("hello, bag")},
      {1, test::encode(imu())},
      {0, test::encode(ouster_cloud())},
  };
  for (std::size_t i = 0; i < messages.size(); ++i) {
    mcap::Message m;
    m.channelId = topics[messages[i].first].channel;
    m.sequence = static_cast<std::uint32_t>(i);
    m.logTime = static_cast<mcap::Timestamp>(t0 + std::int64_t(i) * 10000000);
    m.publishTime = m.logTime;
    m.data = reinterpret_cast<const std::byte*>(messages[i].second.data());
    m.dataSize = messages[i].second.size();
    const mcap::Status written = writer.write(m);
    ASSERT_TRUE(written.ok()) << written.message;
  }
  writer.close();
}

void write_file(const fs::path& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

// Writes the generated seeds into the source tree's corpus (run on demand, see the top).
TEST(FuzzCorpus, DISABLED_WriteSeeds) {
  fs::create_directories(corpus_dir("message"));
  fs::create_directories(corpus_dir("mcap"));
  for (const auto& [name, bytes] : message_seeds()) write_file(corpus_dir("message") / name, bytes);
  const fs::path mcap = corpus_dir("mcap");
  write_sensor_mcap(mcap / "valid_sensors_zstd", mcap::Compression::Zstd, 1024);
  write_sensor_mcap(mcap / "valid_sensors_lz4", mcap::Compression::Lz4, 1024);
  write_sensor_mcap(mcap / "valid_sensors_unchunked", mcap::Compression::None, 0);
  // A recording cut off mid-file (no summary, no footer): read up to the last intact record.
  const fs::path cut = mcap / "valid_sensors_cut";
  write_sensor_mcap(cut, mcap::Compression::Zstd, 1024);
  fs::resize_file(cut, fs::file_size(cut) / 2);
}

// The seeds on disk are the ones the generator writes (no stale or hand-edited seed).
TEST(FuzzCorpus, MessageSeedsMatchGenerator) {
  const auto files = corpus("message");
  for (const auto& [name, bytes] : message_seeds()) {
    ASSERT_TRUE(files.count(name)) << "seed " << name << " missing; run DISABLED_WriteSeeds";
    EXPECT_EQ(files.at(name), bytes) << name;
  }
}

TEST(FuzzCorpus, MessageInputsDecodeWithoutCrashing) {
  const auto files = corpus("message");
  ASSERT_GE(files.size(), 12u) << "corpus missing under modules/bag/fuzz/corpus/message";
  for (const auto& [name, bytes] : files) {
    const int decoded = fuzz::message_input(bytes.data(), bytes.size());
    // Valid seeds decode (and clouds extract: 2); findings are refused or decode harmlessly.
    if (name.rfind("valid_cloud", 0) == 0) {
      EXPECT_EQ(decoded, 2) << name;
    } else if (name.rfind("valid", 0) == 0) {
      EXPECT_EQ(decoded, 1) << name;
    }
  }
  // The fuzzer's finds. A cloud of width 0 and height 2.2e9 is empty, and its rows are not
  // walked (it took 32 s); a `time` offset of 9e9 s past a 2023 stamp is refused, not an
  // int64 overflow.
  EXPECT_EQ(fuzz::message_input(files.at("crash_zero_width_huge_height").data(),
                                files.at("crash_zero_width_huge_height").size()),
            2);
  EXPECT_EQ(fuzz::message_input(files.at("crash_time_offset_overflow").data(),
                                files.at("crash_time_offset_overflow").size()),
            0);
  // Each decoded message equals what was written.
  const MessageContext cdr{"/t", 0, 0, Serialization::kCdr};
  const MessageContext ros{"/t", 0, 0, Serialization::kRos1};
  auto body = [&](const std::string& name) {
    const Bytes& b = files.at(name);
    return std::make_pair(b.data() + 1, b.size() - 1);
  };
  {
    const auto [data, size] = body("valid_camera_info_ros1");
    const CameraInfo info = decode_camera_info(data, size, ros);
    EXPECT_EQ(info.header.seq, 42u);
    EXPECT_EQ(info.d, camera_info().d);
    EXPECT_EQ(info.p, camera_info().p);
  }
  {
    const auto [data, size] = body("valid_cloud_ouster_cdr");
    const PointCloud2 cloud = decode_point_cloud2(data, size, cdr);
    const CloudPoints points = extract_points(cloud, cdr);
    ASSERT_EQ(points.xyz.size(), 6u);
    EXPECT_EQ(points.xyz[4][0], 4.0);
    EXPECT_EQ(points.ring[4], 1u);
    EXPECT_EQ(points.time_ns[4], header("").stamp.to_ns() + 4000);
  }
  {
    const auto [data, size] = body("valid_string_ros1");
    EXPECT_EQ(decode_string(data, size, ros), "hello, bag");
  }
}

TEST(FuzzCorpus, McapInputsReadWithoutCrashing) {
  const auto files = corpus("mcap");
  ASSERT_GE(files.size(), 4u) << "corpus missing under modules/bag/fuzz/corpus/mcap";
  for (const auto& [name, bytes] : files) fuzz::mcap_input(bytes.data(), bytes.size());
  auto read = [&](const std::string& name) {
    const Bytes& b = files.at(name);
    return fuzz::mcap_input(b.data(), b.size());
  };
  EXPECT_EQ(read("valid_sensors_zstd"), 8);
  EXPECT_EQ(read("valid_sensors_lz4"), 8);
  EXPECT_EQ(read("valid_sensors_unchunked"), 8);
  const int cut = read("valid_sensors_cut");
  EXPECT_GE(cut, 1);
  EXPECT_LT(cut, 8);
  // The fuzzer's find: an lz4 chunk (without footer, so read by the scan) stating an
  // uncompressed_size of 5e18 bytes, which the mcap library would allocate; refused first.
  EXPECT_EQ(read("alloc_lz4_chunk_uncompressed_size"), -1);
  // The fuzzer's find in the mcap library: a message index pointing past the end of its
  // chunk, read through an empty optional (patched in third_party/mcap); refused now.
  EXPECT_EQ(read("crash_indexed_message_past_chunk_end"), -1);
  // The fuzzer's find: an lz4 Chunk record inside the summary section (where the Footer's
  // summary_start points, off the path of the records walked from the start) stating 4.2 GB
  // uncompressed, which the library allocated while reading the summary; refused first. Its
  // read returned -1 before the fix too (the lz4 data is short), after a 4 GB allocation: the
  // peak memory check below is what catches its return.
  EXPECT_EQ(read("alloc_lz4_chunk_in_summary"), -1);
  // No input of the corpus (each a few kB) may make the reader allocate by what a record
  // claims: this process's peak RSS stays far below the 4.1 GB of the find above (under
  // ASan too, whose shadow and quarantine stay under ~0.5 GB here).
  rusage usage{};
  ASSERT_EQ(getrusage(RUSAGE_SELF, &usage), 0);
  EXPECT_LT(usage.ru_maxrss, 1024 * 1024) << "peak RSS " << usage.ru_maxrss / 1024 << " MB";
  // rosbag2's own test bags, read in place from ../shared/data (not copied into the corpus);
  // to fuzz from them, pass their folder to the fuzzer beside the corpus.
  const fs::path rosbag2 = fs::path(RGBDT_SHARED_DATA_DIR) / "rosbag2";
  for (const auto& [relative, count] :
       {std::pair<const char*, int>{"rosbag2_py/test/resources/mcap/talker/talker.mcap", 20},
        {"rosbag2_tests/resources/mcap/cdr_test/cdr_test_0.mcap", 7}}) {
    std::ifstream in(rosbag2 / relative, std::ios::binary);
    ASSERT_TRUE(in.good()) << "missing real-data file " << rosbag2 / relative;
    const Bytes bytes{std::istreambuf_iterator<char>(in), {}};
    EXPECT_EQ(fuzz::mcap_input(bytes.data(), bytes.size()), count) << relative;
  }
}

}  // namespace
}  // namespace rgbdt::bag
