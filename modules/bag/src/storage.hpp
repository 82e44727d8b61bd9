#pragma once
// One storage file of a bag (an .mcap, a .db3 or a ROS 1 .bag); bag_reader.cpp merges the files of
// a bag.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "rgbdt/bag/reader.hpp"

namespace rgbdt::bag::detail {

struct StoredMessage {
  std::size_t topic = 0;  ///< index into StorageFile::topics()
  std::int64_t log_time_ns = 0;
  const std::uint8_t* data = nullptr;  ///< valid until the next call of StorageFile::next
  std::size_t size = 0;
};

class StorageFile {
 public:
  virtual ~StorageFile() = default;
  /// The file's topics, one entry per name, with the file's message counts.
  virtual const std::vector<TopicInfo>& topics() const = 0;
  /// Selects the messages to read (topic names; empty reads all) in [start_ns, end_ns); call
  /// once, before next().
  virtual void select(const std::unordered_set<std::string>& topics, std::int64_t start_ns,
                      std::int64_t end_ns) = 0;
  /// The next selected message in log-time order; false at the end.
  virtual bool next(StoredMessage& out) = 0;
  virtual const std::filesystem::path& path() const = 0;
  virtual std::string storage_identifier() const = 0;  ///< "mcap" or "sqlite3"
  virtual bool is_complete() const { return true; }    ///< see BagReader::is_complete
};

std::unique_ptr<StorageFile> open_mcap_file(const std::filesystem::path& path);
std::unique_ptr<StorageFile> open_sqlite_file(const std::filesystem::path& path);
#ifdef RGBDT_BAG_HAVE_ROS1
std::unique_ptr<StorageFile> open_ros1_file(const std::filesystem::path& path);
#endif

/// Adds a channel's topic to `topics` (one entry per name), or its count to the entry of the
/// same name; throws core::Error naming `path` when the types differ. Returns the index.
std::size_t merge_topic(std::vector<TopicInfo>& topics, const TopicInfo& topic,
                        const std::filesystem::path& path);

}  // namespace rgbdt::bag::detail
