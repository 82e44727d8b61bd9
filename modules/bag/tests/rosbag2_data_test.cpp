// Bags that rosbag2's own test suite wrote (../shared/data/rosbag2), read through open_bag and
// checked against the metadata.yaml that rosbag2 wrote beside them.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <regex>

#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

namespace fs = std::filesystem;

fs::path rosbag2_data() { return fs::path(RGBDT_SHARED_DATA_DIR) / "rosbag2"; }

#define SKIP_WITHOUT(path)                                                                      \
  if (!fs::exists(path)) {                                                                      \
    GTEST_SKIP() << "no " << (path) << ": set RGBDT_SHARED_DATA_DIR to the shared data folder"; \
  }

struct Expected {
  std::map<std::string, TopicInfo> topics;
  std::uint64_t message_count = 0;
  std::int64_t start_ns = 0;
  std::int64_t end_ns = 0;  // starting_time + duration: the last message's time
  std::string storage;
  std::vector<std::string> files;
};

Expected read_metadata(const fs::path& folder) {
  const YAML::Node info =
      YAML::LoadFile((folder / "metadata.yaml").string())["rosbag2_bagfile_information"];
  Expected e;
  e.storage = info["storage_identifier"].as<std::string>();
  e.message_count = info["message_count"].as<std::uint64_t>();
  e.start_ns = info["starting_time"]["nanoseconds_since_epoch"].as<std::int64_t>();
  e.end_ns = e.start_ns + info["duration"]["nanoseconds"].as<std::int64_t>();
  for (const YAML::Node& t : info["topics_with_message_count"]) {
    TopicInfo topic;
    topic.name = t["topic_metadata"]["name"].as<std::string>();
    topic.type = t["topic_metadata"]["type"].as<std::string>();
    topic.serialization_format = t["topic_metadata"]["serialization_format"].as<std::string>();
    topic.message_count = t["message_count"].as<std::uint64_t>();
    e.topics[topic.name] = topic;
  }
  for (const YAML::Node& f : info["relative_file_paths"]) e.files.push_back(f.as<std::string>());
  return e;
}

void expect_matches_metadata(const fs::path& path, const Expected& e) {
  SCOPED_TRACE(path.string());
  const auto reader = open_bag(path);
  EXPECT_EQ(reader->storage_identifier(), e.storage);
  ASSERT_EQ(reader->topics().size(), e.topics.size());
  for (const TopicInfo& topic : reader->topics()) {
    ASSERT_EQ(e.topics.count(topic.name), 1u) << topic.name;
    const TopicInfo& want = e.topics.at(topic.name);
    EXPECT_EQ(topic.type, want.type) << topic.name;
    EXPECT_EQ(topic.serialization_format, want.serialization_format) << topic.name;
    EXPECT_EQ(topic.message_count, want.message_count) << topic.name;
  }
  std::map<std::string, std::uint64_t> counts;
  std::uint64_t n = 0;
  std::int64_t first = 0, last = 0;
  while (const auto message = reader->next()) {
    ASSERT_NE(message->topic, nullptr);
    EXPECT_EQ(message->index, n);
    if (n == 0) first = message->log_time_ns;
    EXPECT_GE(message->log_time_ns, last) << "message " << n << " is out of time order";
    last = message->log_time_ns;
    ++counts[message->topic->name];
    // Every ROS 2 message starts with the CDR little-endian encapsulation header.
    ASSERT_GE(message->size, 4u);
    EXPECT_EQ(message->data[0], 0x00);
    EXPECT_EQ(message->data[1], 0x01);
    ++n;
  }
  EXPECT_EQ(n, e.message_count);
  EXPECT_EQ(first, e.start_ns);
  EXPECT_EQ(last, e.end_ns);
  for (const auto& [name, topic] : e.topics) EXPECT_EQ(counts[name], topic.message_count) << name;
}

class Rosbag2CdrTest : public testing::TestWithParam<std::string> {};

TEST_P(Rosbag2CdrTest, FolderAndFileMatchMetadata) {
  const fs::path folder = rosbag2_data() / "rosbag2_tests/resources" / GetParam() / "cdr_test";
  SKIP_WITHOUT(folder);
  const Expected e = read_metadata(folder);
  ASSERT_EQ(e.storage, GetParam());
  ASSERT_EQ(e.message_count, 7u);  // guards against an empty or replaced metadata.yaml
  expect_matches_metadata(folder, e);
  ASSERT_EQ(e.files.size(), 1u);
  expect_matches_metadata(folder / e.files[0], e);
}

TEST_P(Rosbag2CdrTest, TopicAndTimeFiltersSelectMessages) {
  const fs::path folder = rosbag2_data() / "rosbag2_tests/resources" / GetParam() / "cdr_test";
  SKIP_WITHOUT(folder);
  const Expected e = read_metadata(folder);
  ReadOptions options;
  options.topics = {"/test_topic"};
  auto reader = open_bag(folder, options);
  std::uint64_t n = 0;
  while (const auto message = reader->next()) {
    EXPECT_EQ(message->topic->name, "/test_topic");
    EXPECT_EQ(message->topic->type, "test_msgs/msg/BasicTypes");
    ++n;
  }
  EXPECT_EQ(n, e.topics.at("/test_topic").message_count);
  // topics() still lists every topic.
  EXPECT_EQ(reader->topics().size(), e.topics.size());

  // [start + 1 ns, end): drops the first and the last message.
  ReadOptions window;
  window.start_ns = e.start_ns + 1;
  window.end_ns = e.end_ns;
  reader = open_bag(folder, window);
  n = 0;
  while (const auto message = reader->next()) {
    EXPECT_GT(message->log_time_ns, e.start_ns);
    EXPECT_LT(message->log_time_ns, e.end_ns);
    ++n;
  }
  EXPECT_EQ(n, e.message_count - 2);

  ReadOptions typo;
  typo.topics = {"/test_topix"};
  EXPECT_THROW(open_bag(folder, typo), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Storage, Rosbag2CdrTest, testing::Values("mcap", "sqlite3"));

// The talker bags of rosbag2_py's tests come without metadata.yaml: a folder of one file.
// Their std_msgs/String messages are the demo talker's "Hello, world! <n>", n counting up.
class Rosbag2TalkerTest : public testing::TestWithParam<std::string> {};

TEST_P(Rosbag2TalkerTest, StringsAreTheTalkersCountingHellos) {
  const fs::path folder = rosbag2_data() / "rosbag2_py/test/resources" / GetParam() / "talker";
  SKIP_WITHOUT(folder);
  ReadOptions options;
  options.topics = {"/topic"};
  const auto reader = open_bag(folder, options);
  const TopicInfo* topic = reader->find_topic("/topic");
  ASSERT_NE(topic, nullptr);
  EXPECT_EQ(topic->type, "std_msgs/msg/String");
  EXPECT_EQ(topic->serialization_format, "cdr");
  const TopicInfo* rosout = reader->find_topic("/rosout");
  ASSERT_NE(rosout, nullptr);
  EXPECT_EQ(rosout->type, "rcl_interfaces/msg/Log");

  const std::regex hello("Hello, world! ([0-9]+)");
  std::uint64_t n = 0;
  long previous = -1;
  std::int64_t previous_ns = 0;
  while (const auto message = reader->next()) {
    const std::string text = decode_string(message->data, message->size, context_of(*message));
    std::smatch match;
    ASSERT_TRUE(std::regex_match(text, match, hello)) << "message " << n << ": " << text;
    const long count = std::stol(match[1]);
    if (previous >= 0) {
      EXPECT_EQ(count, previous + 1) << text;
      // The talker publishes at 2 Hz.
      EXPECT_NEAR(double(message->log_time_ns - previous_ns) * 1e-9, 0.5, 0.1);
    }
    previous = count;
    previous_ns = message->log_time_ns;
    ++n;
  }
  EXPECT_EQ(n, topic->message_count);
  EXPECT_EQ(n, 10u);
  EXPECT_EQ(previous, 9);  // "Hello, world! 0" .. "Hello, world! 9"
}

TEST_P(Rosbag2TalkerTest, RosoutIsNotAString) {
  const fs::path folder = rosbag2_data() / "rosbag2_py/test/resources" / GetParam() / "talker";
  SKIP_WITHOUT(folder);
  ReadOptions options;
  options.topics = {"/rosout"};
  const auto reader = open_bag(folder, options);
  const auto message = reader->next();
  ASSERT_TRUE(message.has_value());
  // rcl_interfaces/msg/Log starts with a Time: its seconds, read as a string length, exceed
  // the message.
  try {
    decode_string(message->data, message->size, context_of(*message));
    FAIL() << "a Log message decoded as a String";
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("topic /rosout, message 0 at 1585866235."), std::string::npos) << what;
    EXPECT_NE(what.find("std_msgs/msg/String field data"), std::string::npos) << what;
  }
}

INSTANTIATE_TEST_SUITE_P(Storage, Rosbag2TalkerTest, testing::Values("mcap", "sqlite3"));

// The MCAP talker bag is a conversion of the sqlite3 one: the same messages, byte for byte.
TEST(Rosbag2Talker, McapAndSqliteHoldTheSameMessages) {
  const fs::path root = rosbag2_data() / "rosbag2_py/test/resources";
  SKIP_WITHOUT(root / "mcap/talker");
  SKIP_WITHOUT(root / "sqlite3/talker");
  const auto mcap = open_bag(root / "mcap/talker/talker.mcap");
  const auto sqlite = open_bag(root / "sqlite3/talker/talker.db3");
  ASSERT_EQ(mcap->topics().size(), 3u);
  ASSERT_EQ(sqlite->topics().size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(mcap->topics()[i].name, sqlite->topics()[i].name);
    EXPECT_EQ(mcap->topics()[i].type, sqlite->topics()[i].type);
    EXPECT_EQ(mcap->topics()[i].message_count, sqlite->topics()[i].message_count);
  }
  std::uint64_t n = 0;
  while (true) {
    const auto a = mcap->next();
    const auto b = sqlite->next();
    ASSERT_EQ(a.has_value(), b.has_value()) << "after " << n << " messages";
    if (!a) break;
    EXPECT_EQ(a->topic->name, b->topic->name);
    EXPECT_EQ(a->log_time_ns, b->log_time_ns);
    EXPECT_EQ(std::vector<std::uint8_t>(a->data, a->data + a->size),
              std::vector<std::uint8_t>(b->data, b->data + b->size));
    ++n;
  }
  EXPECT_EQ(n, 20u);  // 10 on /rosout, 10 on /topic, none on /parameter_events
}

TEST(OpenBag, MissingPathAndWrongFormatAreNamed) {
  try {
    open_bag("/nonexistent/bag.mcap");
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/bag.mcap: does not exist");
  }
  const fs::path metadata = rosbag2_data() / "rosbag2_tests/resources/mcap/cdr_test/metadata.yaml";
  SKIP_WITHOUT(metadata);
  try {
    open_bag(metadata);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("is neither an MCAP file"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rgbdt::bag
