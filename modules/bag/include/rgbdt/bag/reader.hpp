#pragma once
/// \file
/// Reading ROS bags: the topics a bag holds and its messages, as serialized bytes, in log-time
/// order. Messages are streamed, one at a time, so memory does not grow with the bag's size;
/// decoding the bytes is rgbdt/bag/messages.hpp's job.
///
/// Formats: ROS 2 MCAP (.mcap; uncompressed, zstd or lz4 chunks), ROS 2 sqlite3 (.db3) and,
/// when built with librosbag-storage-dev, ROS 1 bags (.bag format 2.0; messages in ROS 1
/// serialization, not CDR). `open_bag` takes a single bag file or a folder (a rosbag2 folder
/// with metadata.yaml, or only the files). Problems with a bag throw rgbdt::core::Error naming
/// the file.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rgbdt::bag {

/// One topic of a bag.
struct TopicInfo {
  std::string name;                  ///< e.g. "/velodyne_points"
  std::string type;                  ///< ROS type name, e.g. "sensor_msgs/msg/PointCloud2"
  std::string serialization_format;  ///< "cdr" for ROS 2, "ros1" for ROS 1 bags
  std::uint64_t message_count = 0;   ///< messages of this topic in the whole bag
};

/// One message as stored. `data` points into the reader's buffer and stays valid until the
/// next call of BagReader::next (copy it to keep it).
struct BagMessage {
  const TopicInfo* topic = nullptr;    ///< points into BagReader::topics()
  std::int64_t log_time_ns = 0;        ///< when the recorder received it [ns since epoch]
  const std::uint8_t* data = nullptr;  ///< serialized message (CDR for ROS 2)
  std::size_t size = 0;                ///< bytes at `data`
  std::uint64_t index = 0;             ///< 0-based count of messages returned before this one
};

struct ReadOptions {
  /// Topics to read; empty reads every topic. A name the bag does not hold is an error (a
  /// typo would otherwise read nothing silently).
  std::vector<std::string> topics;
  /// Messages with start_ns <= log time < end_ns are read [ns since epoch].
  std::int64_t start_ns = std::numeric_limits<std::int64_t>::min();
  std::int64_t end_ns = std::numeric_limits<std::int64_t>::max();
};

/// A bag opened for reading. Not copyable; one reader reads one pass through the bag.
class BagReader {
 public:
  virtual ~BagReader() = default;
  BagReader(const BagReader&) = delete;
  BagReader& operator=(const BagReader&) = delete;

  /// Every topic of the bag (not only the selected ones), sorted by name.
  virtual const std::vector<TopicInfo>& topics() const = 0;

  /// The next selected message in log-time order (ties in storage order), or nullopt at the
  /// end. Throws core::Error when the bag is damaged.
  virtual std::optional<BagMessage> next() = 0;

  /// "mcap" or "sqlite3" (rosbag2's storage identifiers) or "ros1".
  virtual const std::string& storage_identifier() const = 0;

  /// False when an MCAP file lacks its summary and footer, as when the recorder was killed:
  /// the messages up to the last intact record are read (and counted in topics()), in the
  /// order the recorder wrote them (its receive order, so log-time order unless the writer
  /// reordered), and the rest of the recording is lost. Damaged records throw instead.
  virtual bool is_complete() const = 0;

  /// The topic named `name`, or nullptr.
  const TopicInfo* find_topic(const std::string& name) const;

 protected:
  BagReader() = default;
};

/// Opens a bag file (.mcap, .db3, .bag; told apart by their first bytes) or a bag folder. A
/// folder's files come from its metadata.yaml (relative_file_paths) when it has one, else they
/// are the folder's .mcap, .db3 and .bag files in name order; the messages of all files are
/// merged in log-time order.
/// Throws core::Error when the path, a file or its format cannot be read, and
/// std::invalid_argument when options name a topic the bag does not hold or start_ns > end_ns.
std::unique_ptr<BagReader> open_bag(const std::filesystem::path& path,
                                    const ReadOptions& options = {});

}  // namespace rgbdt::bag
