// ROS 1 bags (format 2.0, uncompressed, bz2 or lz4 chunks) through Debian's
// librosbag-storage-dev. Messages come out in ROS 1 serialization (serialization_format
// "ros1"), not CDR. rosbag::View keeps an index entry per selected message in memory (tens of
// bytes each), the message bytes are read one at a time.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <limits>
#include <unordered_map>

#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag::detail {
namespace {

// The stream MessageInstance::write copies a message's bytes into.
struct ByteSink {
  std::vector<std::uint8_t>& bytes;
  std::uint8_t* advance(std::uint32_t n) {
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

class Ros1File : public StorageFile {
 public:
  explicit Ros1File(const std::filesystem::path& path) : path_(path) {
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
