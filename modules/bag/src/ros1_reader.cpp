// ROS 1 bags (format 2.0, uncompressed, bz2 or lz4 chunks) through Debian's
// librosbag-storage-dev. Messages come out in ROS 1 serialization (serialization_format
// "ros1"), not CDR. rosbag::View keeps an index entry per selected message in memory (tens of
// bytes each), the message bytes are read one at a time.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <unordered_map>

#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag::detail {
namespace {

constexpr std::uint32_t kMaxMessageBytes = 1u << 30;

// The stream MessageInstance::write copies a message's bytes into.
struct ByteSink {
  std::vector<std::uint8_t>& bytes;
  std::uint8_t* advance(std::uint32_t n) {
    // A message inside a chunk cannot be larger than the chunk (check_records bounds those).
    if (n > kMaxMessageBytes)
      throw std::length_error("a message claims " + std::to_string(n) + " bytes");
    const std::size_t old = bytes.size();
    bytes.resize(old + n);
    return bytes.data() + old;
  }
};

// ros::Time holds unsigned 32-bit seconds.
constexpr std::int64_t kMaxRosTimeNs = std::int64_t{0xFFFFFFFF} * 1000000000 + 999999999;

ros::Time to_ros_time(std::int64_t ns) {
  ros::Time t;
  t.fromNSec(static_cast<std::uint64_t>(std::clamp<std::int64_t>(ns, 0, kMaxRosTimeNs)));
  return t;
}

// Largest chunk (uncompressed) and record header accepted: the recorder writes chunks of
// 768 kB by default and headers of a few hundred bytes.
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 30;
constexpr std::uint32_t kMaxHeaderBytes = 16u << 20;

std::uint32_t le32(const char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;  // the bag format is little endian, as every host rosbag runs on
}

// Walks the top-level records of a ROS 1 bag (format 2.0: header length, header fields
// `name=value`, data length, data) and checks that every length fits in the file and that a
// chunk's uncompressed size is within kMaxChunkBytes (equal to its data for "none").
// librosbag sizes its buffers from these fields unchecked, and a failed allocation ends the
// process in an assert (Buffer::ensureCapacity), so a damaged or hostile bag is refused here
// with the byte offset instead. Reads only the headers: a few kB per MB of bag.
void check_records(const std::filesystem::path& path) {
  const auto fail_at = [&](std::uint64_t at, const std::string& what) {
    throw core::Error(path.string(), "not a readable ROS 1 bag: the record at byte " +
                                         std::to_string(at) + " " + what);
  };
  std::ifstream in(path, std::ios::binary);
  const std::uint64_t file_size = std::filesystem::file_size(path);
  std::uint64_t at = 13;  // after "#ROSBAG V2.0\n"
  std::string header;
  char word[4];
  while (at < file_size) {
    if (file_size - at < 4)
      fail_at(at, "is cut: " + std::to_string(file_size - at) + " bytes left, expected a length");
    in.seekg(static_cast<std::streamoff>(at));
    in.read(word, 4);
    const std::uint32_t header_len = le32(word);
    if (header_len > kMaxHeaderBytes || header_len + std::uint64_t{8} > file_size - at) {
      fail_at(at, "claims a header of " + std::to_string(header_len) +
                      " bytes, beyond the file's " + std::to_string(file_size - at - 4) +
                      " remaining bytes (the file is damaged or cut)");
    }
    header.resize(header_len);
    in.read(header.data(), header_len);
    in.read(word, 4);
    if (!in) fail_at(at, "cannot be read");
    const std::uint32_t data_len = le32(word);
    const std::uint64_t end = at + 8 + std::uint64_t{header_len} + data_len;
    if (end > file_size) {
      fail_at(at, "claims " + std::to_string(data_len) +
                      " bytes of data, beyond the file's end (the file is damaged or cut)");
    }
    int op = -1;
    std::uint64_t chunk_size = 0;
    std::string compression;
    for (std::size_t p = 0; p < header.size();) {
      if (header.size() - p < 4) fail_at(at, "has a header field cut short");
      const std::uint32_t field_len = le32(header.data() + p);
      if (field_len > header.size() - p - 4)
        fail_at(at, "has a header field longer than its header");
      const std::string field = header.substr(p + 4, field_len);
      p += 4 + std::size_t{field_len};
      const auto eq = field.find('=');
      if (eq == std::string::npos) fail_at(at, "has a header field without '='");
      const std::string name = field.substr(0, eq), value = field.substr(eq + 1);
      if (name == "op" && value.size() == 1) op = static_cast<unsigned char>(value[0]);
      if (name == "size" && value.size() == 4) chunk_size = le32(value.data());
      if (name == "compression") compression = value;
    }
    if (op == 0x05) {  // a chunk
      if (compression == "none" ? chunk_size != data_len : chunk_size > kMaxChunkBytes) {
        fail_at(at, "is a chunk (" + compression + ") claiming " + std::to_string(chunk_size) +
                        " bytes uncompressed from " + std::to_string(data_len) + " stored");
      }
    }
    at = end;
  }
}

class Ros1File : public StorageFile {
 public:
  explicit Ros1File(const std::filesystem::path& path) : path_(path) {
    check_records(path);
    try {
      bag_.open(path.string(), rosbag::bagmode::Read);
      rosbag::View all(bag_);
      std::vector<TopicInfo> found;
      for (const rosbag::ConnectionInfo* connection : all.getConnections()) {
        merge_topic(found, {connection->topic, connection->datatype, "ros1", 0}, path_);
      }
      std::sort(found.begin(), found.end(),
                [](const TopicInfo& a, const TopicInfo& b) { return a.name < b.name; });
      for (TopicInfo& topic : found) {
        topic.message_count = rosbag::View(bag_, rosbag::TopicQuery(topic.name)).size();
        topic_index_[topic.name] = topics_.size();
        topics_.push_back(topic);
      }
    } catch (const rosbag::BagException& e) {
      fail(std::string("cannot read as a ROS 1 bag (a bag whose recorder was killed needs "
                       "`rosbag reindex`): ") +
           e.what());
    }
  }

  const std::vector<TopicInfo>& topics() const override { return topics_; }
  const std::filesystem::path& path() const override { return path_; }
  std::string storage_identifier() const override { return "ros1"; }

  void select(const std::unordered_set<std::string>& topics, std::int64_t start_ns,
              std::int64_t end_ns) override {
    end_ns_ = end_ns;
    if (start_ns > kMaxRosTimeNs || end_ns <= 0) {
      done_ = true;
      return;
    }
    try {
      // View's end time is inclusive; next() drops messages at end_ns.
      if (topics.empty()) {
        view_ = std::make_unique<rosbag::View>(bag_, to_ros_time(start_ns), to_ros_time(end_ns));
      } else {
        const std::vector<std::string> names(topics.begin(), topics.end());
        view_ = std::make_unique<rosbag::View>(bag_, rosbag::TopicQuery(names),
                                               to_ros_time(start_ns), to_ros_time(end_ns));
      }
      it_ = view_->begin();
    } catch (const rosbag::BagException& e) {
      fail(std::string("cannot read the bag's index: ") + e.what());
    }
  }

  bool next(StoredMessage& out) override {
    if (!view_ && !done_) {
      select({}, std::numeric_limits<std::int64_t>::min(),
             std::numeric_limits<std::int64_t>::max());
    }
    if (done_) return false;
    try {
      if (started_) ++it_;
      started_ = true;
      if (it_ == view_->end()) return false;
      const rosbag::MessageInstance& message = *it_;
      const std::int64_t t = static_cast<std::int64_t>(message.getTime().toNSec());
      if (t >= end_ns_) {
        done_ = true;
        return false;
      }
      const auto topic = topic_index_.find(message.getTopic());
      if (topic == topic_index_.end()) fail("a message has unknown topic " + message.getTopic());
      bytes_.clear();
      ByteSink sink{bytes_};
      message.write(sink);
      out.topic = topic->second;
      out.log_time_ns = t;
      out.data = bytes_.data();
      out.size = bytes_.size();
      return true;
    } catch (const rosbag::BagException& e) {
      fail(std::string("cannot read a message: ") + e.what());
    } catch (const std::length_error& e) {
      fail(std::string("cannot read a message: ") + e.what());
    }
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw core::Error(path_.string(), what); }

  std::filesystem::path path_;
  rosbag::Bag bag_;
  std::vector<TopicInfo> topics_;
  std::unordered_map<std::string, std::size_t> topic_index_;
  std::unique_ptr<rosbag::View> view_;
  rosbag::View::iterator it_;
  bool started_ = false;
  bool done_ = false;
  std::int64_t end_ns_ = std::numeric_limits<std::int64_t>::max();
  std::vector<std::uint8_t> bytes_;
};

}  // namespace

std::unique_ptr<StorageFile> open_ros1_file(const std::filesystem::path& path) {
  return std::make_unique<Ros1File>(path);
}

}  // namespace rgbdt::bag::detail
