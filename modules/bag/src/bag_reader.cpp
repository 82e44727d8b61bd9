#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <stdexcept>

#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag {

namespace fs = std::filesystem;

const TopicInfo* BagReader::find_topic(const std::string& name) const {
  for (const TopicInfo& topic : topics()) {
    if (topic.name == name) return &topic;
  }
  return nullptr;
}

namespace detail {

std::size_t merge_topic(std::vector<TopicInfo>& topics, const TopicInfo& topic,
                        const fs::path& path) {
  for (std::size_t i = 0; i < topics.size(); ++i) {
    TopicInfo& known = topics[i];
    if (known.name != topic.name) continue;
    if (known.type != topic.type || known.serialization_format != topic.serialization_format) {
      throw core::Error(path.string(), "topic " + topic.name + " has two types, " + known.type +
                                           " (" + known.serialization_format + ") and " +
                                           topic.type + " (" + topic.serialization_format +
                                           "); rgbdt reads one type per topic");
    }
    known.message_count += topic.message_count;
    return i;
  }
  topics.push_back(topic);
  return topics.size() - 1;
}

}  // namespace detail

namespace {

using detail::StorageFile;
using detail::StoredMessage;

enum class FileKind { kMcap, kSqlite, kRos1 };

// Tells the storage format from the first bytes, so that a renamed file still opens and a
// ROS 1 bag or a file-compressed rosbag2 file is named as such.
FileKind sniff(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path.string(), "cannot open the file");
  char magic[16] = {};
  in.read(magic, sizeof(magic));
  const std::string head(magic, static_cast<std::size_t>(in.gcount()));
  if (head.compare(0, 8, "\x89MCAP0\r\n") == 0) return FileKind::kMcap;
  if (head.compare(0, 16, std::string("SQLite format 3\0", 16)) == 0) return FileKind::kSqlite;
  if (head.compare(0, 13, "#ROSBAG V2.0\n") == 0) {
#ifdef RGBDT_BAG_HAVE_ROS1
    return FileKind::kRos1;
#else
    throw core::Error(path.string(),
                      "is a ROS 1 bag, and this rgbdt was built without librosbag-storage-dev");
#endif
  }
  if (head.compare(0, 9, "#ROSBAG V") == 0) {
    throw core::Error(path.string(), "is a ROS 1 bag of format " + head.substr(9, 3) +
                                         ", expected format 2.0 (ROS 1 since 2010): migrate it "
                                         "with `rosbag fix`");
  }
  if (head.compare(0, 4, "\x28\xb5\x2f\xfd") == 0) {
    throw core::Error(path.string(),
                      "is zstd-compressed as a whole (rosbag2 compression_mode FILE); decompress "
                      "it with `zstd -d` first");
  }
  throw core::Error(path.string(),
                    "is neither an MCAP file (magic \\x89MCAP0), an sqlite3 database (magic "
                    "'SQLite format 3') nor a ROS 1 bag (#ROSBAG V2.0), expected a ROS bag file");
}

std::unique_ptr<StorageFile> open_file(const fs::path& path) {
  switch (sniff(path)) {
    case FileKind::kMcap:
      return detail::open_mcap_file(path);
    case FileKind::kSqlite:
      return detail::open_sqlite_file(path);
    case FileKind::kRos1:
#ifdef RGBDT_BAG_HAVE_ROS1
      return detail::open_ros1_file(path);
#endif
      break;
  }
  throw core::Error(path.string(), "has no reader");
}

// The storage files of a bag folder: from metadata.yaml when present, else the folder's .mcap,
// .db3 and .bag files in name order.
std::vector<fs::path> bag_files(const fs::path& folder) {
  const fs::path metadata = folder / "metadata.yaml";
  std::vector<fs::path> files;
  if (fs::exists(metadata)) {
    const std::string source = metadata.string();
    YAML::Node info;
    try {
      info = YAML::LoadFile(source)["rosbag2_bagfile_information"];
    } catch (const YAML::Exception& e) {
      throw core::Error(source, std::string("is not valid YAML: ") + e.what());
    }
    if (!info || !info.IsMap()) {
      throw core::Error(source,
                        "has no map 'rosbag2_bagfile_information', expected rosbag2 "
                        "bag metadata");
    }
    const YAML::Node mode = info["compression_mode"];
    const std::string compression_mode = mode && mode.IsScalar() ? mode.as<std::string>() : "";
    if (!compression_mode.empty() && compression_mode != "NONE") {
      throw core::Error(source, "compression_mode is '" + compression_mode +
                                    "'; rgbdt reads uncompressed bags (MCAP chunk compression "
                                    "is fine): decompress with `ros2 bag convert`");
    }
    const YAML::Node paths = info["relative_file_paths"];
    if (!paths || !paths.IsSequence() || paths.size() == 0) {
      throw core::Error(source,
                        "relative_file_paths is missing or empty, expected the bag's "
                        "files");
    }
    for (const YAML::Node& p : paths) {
      const fs::path relative = p.as<std::string>();
      fs::path file = folder / relative;
      // rosbag2 before metadata version 4 wrote the paths relative to the folder's parent.
      if (!fs::exists(file) && fs::exists(folder.parent_path() / relative)) {
        file = folder.parent_path() / relative;
      }
      if (!fs::exists(file)) {
        throw core::Error(
            source, "lists file '" + relative.string() + "', which is not in " + folder.string());
      }
      files.push_back(file);
    }
    return files;
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(folder)) {
    const std::string ext = entry.path().extension().string();
    if (entry.is_regular_file() && (ext == ".mcap" || ext == ".db3" || ext == ".bag")) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    throw core::Error(folder.string(),
                      "holds no metadata.yaml and no .mcap, .db3 or .bag file, expected a bag "
                      "folder");
  }
  return files;
}

// The messages of all files of a bag, merged in log-time order (ties: earlier file first).
class MergedReader : public BagReader {
 public:
  MergedReader(std::vector<std::unique_ptr<StorageFile>> files, const ReadOptions& options)
      : files_(std::move(files)) {
    if (options.start_ns > options.end_ns) {
      throw std::invalid_argument("ReadOptions start_ns " + std::to_string(options.start_ns) +
                                  " is after end_ns " + std::to_string(options.end_ns));
    }
    for (const auto& file : files_) {
      for (const TopicInfo& topic : file->topics()) {
        detail::merge_topic(topics_, topic, file->path());
      }
    }
    std::sort(topics_.begin(), topics_.end(),
              [](const TopicInfo& a, const TopicInfo& b) { return a.name < b.name; });
    const std::unordered_set<std::string> selected(options.topics.begin(), options.topics.end());
    for (const std::string& name : selected) {
      if (!find_topic(name)) {
        std::string known;
        for (const TopicInfo& topic : topics_) known += (known.empty() ? "" : ", ") + topic.name;
        throw std::invalid_argument("topic '" + name + "' is not in the bag; it holds: " + known);
      }
    }
    for (const auto& file : files_) {
      std::vector<const TopicInfo*> map;
      for (const TopicInfo& topic : file->topics()) map.push_back(find_topic(topic.name));
      file_topics_.push_back(std::move(map));
      file->select(selected, options.start_ns, options.end_ns);
    }
    heads_.resize(files_.size());
    for (std::size_t i = 0; i < files_.size(); ++i) advance(i);
    storage_ = files_.front()->storage_identifier();
  }

  const std::vector<TopicInfo>& topics() const override { return topics_; }
  const std::string& storage_identifier() const override { return storage_; }
  bool is_complete() const override {
    return std::all_of(files_.begin(), files_.end(),
                       [](const auto& file) { return file->is_complete(); });
  }

  std::optional<BagMessage> next() override {
    if (pending_) {
      advance(*pending_);
      pending_.reset();
    }
    std::optional<std::size_t> best;
    for (std::size_t i = 0; i < heads_.size(); ++i) {
      if (heads_[i] && (!best || heads_[i]->log_time_ns < heads_[*best]->log_time_ns)) best = i;
    }
    if (!best) return std::nullopt;
    // The message's bytes stay valid until this file advances, at the next call.
    pending_ = best;
    const StoredMessage& stored = *heads_[*best];
    BagMessage message;
    message.topic = file_topics_[*best][stored.topic];
    message.log_time_ns = stored.log_time_ns;
    message.data = stored.data;
    message.size = stored.size;
    message.index = count_++;
    return message;
  }

 private:
  void advance(std::size_t i) {
    StoredMessage message;
    if (files_[i]->next(message)) {
      heads_[i] = message;
    } else {
      heads_[i].reset();
    }
  }

  std::vector<std::unique_ptr<StorageFile>> files_;
  std::vector<std::vector<const TopicInfo*>> file_topics_;  // file's topic index -> topics_
  std::vector<std::optional<StoredMessage>> heads_;         // each file's next message
  std::optional<std::size_t> pending_;                      // the file to advance first
  std::vector<TopicInfo> topics_;
  std::string storage_;
  std::uint64_t count_ = 0;
};

}  // namespace

std::unique_ptr<BagReader> open_bag(const fs::path& path, const ReadOptions& options) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw core::Error(path.string(), "does not exist");
  std::vector<fs::path> paths = fs::is_directory(status) ? bag_files(path) : std::vector{path};
  std::vector<std::unique_ptr<StorageFile>> files;
  for (const fs::path& p : paths) files.push_back(open_file(p));
  return std::make_unique<MergedReader>(std::move(files), options);
}

}  // namespace rgbdt::bag
