// ROS 2 MCAP files through the vendored mcap library (third_party/mcap).
#include <lz4frame.h>
#include <zstd.h>
#include <mcap/reader.hpp>

#include <algorithm>
#include <fstream>
#include <limits>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag::detail {
namespace {

std::uint64_t load_u64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
std::uint32_t load_u32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
         std::uint32_t(p[3]) << 24;
}

// The mcap library allocates a chunk's uncompressed_size, as the Chunk record states it, before
// it decompresses (and asserts that it equals the stored size of an uncompressed chunk), so a
// damaged or hostile record would ask for up to 2^64 bytes. This checks the Chunk records the
// library can decompress before it reads them: uncompressed_size must be what the compressed
// bytes can produce (the size a zstd frame declares; at most 255 x for lz4 (its longest match
// costs a byte per 255), 32768 x for a zstd frame without size (an RLE block of 128 KiB in 4
// bytes); equal for no compression).
class ChunkChecker {
 public:
  explicit ChunkChecker(const std::filesystem::path& path)
      : path_(path), in_(path, std::ios::binary) {
    std::error_code ec;
    size_ = std::filesystem::file_size(path, ec);
    if (ec || !in_) size_ = 0;
  }

  // Checks every Chunk record from `offset` on, record by record, as the library scans.
  void walk(std::uint64_t offset) {
    std::uint8_t head[9];
    while (size_ >= offset && size_ - offset >= 9 && read(offset, head, 9)) {
      const std::uint64_t length = load_u64(head + 1);
      if (length > size_ - offset - 9) return;  // truncated: the library reports it
      if (head[0] == 0x06) check_chunk(offset);
      if (head[0] == 0x02) return;  // Footer
      offset += 9 + length;
    }
  }

  // Checks the records the library reads as the summary section: from the Footer's
  // summary_start (and summary_offset_start) on. A hostile file can put a Chunk there, off the
  // path of the walk from the start, and the library decompresses it while reading the summary.
  void walk_summary() {
    // Footer: opcode, record length, summary_start, summary_offset_start, summary_crc; magic.
    std::uint8_t footer[9 + 20];
    if (size_ < sizeof(footer) + 8 || !read(size_ - 8 - sizeof(footer), footer, sizeof(footer)) ||
        footer[0] != 0x02) {
      return;  // no footer: the library scans from the start, which walk(8) covered
    }
    for (const std::uint64_t start : {load_u64(footer + 9), load_u64(footer + 17)}) {
      if (start != 0) walk(start);
    }
  }

  bool checked(std::uint64_t offset) const { return checked_.count(offset) > 0; }

  // Checks the Chunk record starting at `offset`, if there is one.
  void check_chunk(std::uint64_t offset) {
    if (!checked_.insert(offset).second) return;
    // opcode, record length, start and end time, uncompressed_size, crc, compression length
    std::uint8_t head[9 + 32];
    if (size_ < offset || size_ - offset < sizeof(head) || !read(offset, head, sizeof(head)))
      return;
    if (head[0] != 0x06) return;
    const std::uint64_t length = load_u64(head + 1);
    const std::uint64_t uncompressed = load_u64(head + 9 + 16);
    const std::uint32_t name_length = load_u32(head + 9 + 28);
    if (length > size_ - offset - 9 || length < 32 || name_length > 16 ||
        length - 32 < std::uint64_t{name_length} + 8) {
      return;  // malformed: the library refuses it without allocating
    }
    std::uint8_t rest[16 + 8];
    if (!read(offset + 9 + 32, rest, name_length + 8)) return;
    const std::string compression(reinterpret_cast<const char*>(rest), name_length);
    const std::uint64_t compressed = load_u64(rest + name_length);
    const std::uint64_t data = offset + 9 + 32 + name_length + 8;
    if (compressed > length - 32 - name_length - 8) return;  // the library refuses it
    auto refuse = [&](const std::string& why) {
      throw core::Error(path_.string(), "MCAP file is damaged: chunk at byte " +
                                            std::to_string(offset) + " states uncompressed_size " +
                                            std::to_string(uncompressed) + " for " +
                                            std::to_string(compressed) + " bytes of '" +
                                            compression + "' data: " + why);
    };
    if (compression.empty()) {
      if (uncompressed != compressed) refuse("an uncompressed chunk holds as many as it stores");
    } else if (compression == "lz4") {
      if (uncompressed / 255 > compressed) refuse("lz4 expands at most 255 times");
    } else if (compression == "zstd") {
      std::uint8_t frame[18];
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(compressed, 18));
      if (!read(data, frame, n)) return;
      const unsigned long long declared = ZSTD_getFrameContentSize(frame, n);
      if (declared == ZSTD_CONTENTSIZE_ERROR) refuse("the data is not a zstd frame");
      if (declared == ZSTD_CONTENTSIZE_UNKNOWN) {
        if (uncompressed / 32768 > compressed) refuse("zstd expands at most 32768 times");
      } else if (declared != uncompressed) {
        refuse("the zstd frame declares " + std::to_string(declared) + " bytes");
      }
    }
  }

 private:
  bool read(std::uint64_t offset, std::uint8_t* out, std::size_t n) {
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
    return in_.gcount() == static_cast<std::streamsize>(n);
  }

  std::filesystem::path path_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
  std::unordered_set<std::uint64_t> checked_;
};

class McapFile : public StorageFile {
 public:
  explicit McapFile(const std::filesystem::path& path) : path_(path) {
    const mcap::Status opened = reader_.open(path.string());
    if (!opened.ok()) fail("cannot open as MCAP: " + opened.message);
    // Every chunk the scans below or the readers (in file order from the first record, in log
    // time order from the chunk indexes) decompress, checked first, and any Chunk the summary
    // section holds (the library decompresses it while reading the summary).
    ChunkChecker chunks(path_);
    chunks.walk(8);  // the magic, then the records
    chunks.walk_summary();
    // A file without its summary and footer (the recorder did not close it) is scanned up to
    // the last intact record.
    complete_ = reader_.readSummary(mcap::ReadSummaryMethod::NoFallbackScan).ok();
    if (complete_) {
      std::uint64_t first = std::numeric_limits<std::uint64_t>::max();
      for (const mcap::ChunkIndex& index : reader_.chunkIndexes()) {
        first = std::min(first, index.chunkStartOffset);
      }
      // Reading in file order starts at the first indexed chunk: the records from there on,
      // unless the walk from the start already went through it.
      if (first != std::numeric_limits<std::uint64_t>::max() && !chunks.checked(first)) {
        chunks.walk(first);
      }
      for (const mcap::ChunkIndex& index : reader_.chunkIndexes()) {
        chunks.check_chunk(index.chunkStartOffset);
      }
    }
    if (!complete_) {
      const mcap::Status summary =
          reader_.readSummary(mcap::ReadSummaryMethod::ForceScan,
                              [this](const mcap::Status& problem) { note_problem(problem); });
      if (!summary.ok()) fail("cannot read the MCAP summary: " + summary.message);
      throw_problem();
    }

    const auto schemas = reader_.schemas();
    const auto all_channels = reader_.channels();  // a copy: channels() returns by value
    std::vector<std::pair<mcap::ChannelId, mcap::ChannelPtr>> channels(all_channels.begin(),
                                                                       all_channels.end());
    // Sorted by topic so that topics() is sorted by name.
    std::sort(channels.begin(), channels.end(), [](const auto& a, const auto& b) {
      return std::tie(a.second->topic, a.first) < std::tie(b.second->topic, b.first);
    });
    const auto& statistics = reader_.statistics();
    for (const auto& [id, channel] : channels) {
      TopicInfo topic;
      topic.name = channel->topic;
      const auto schema = schemas.find(channel->schemaId);
      if (schema != schemas.end()) topic.type = schema->second->name;
      topic.serialization_format = channel->messageEncoding;
      if (statistics) {
        const auto count = statistics->channelMessageCounts.find(id);
        if (count != statistics->channelMessageCounts.end()) topic.message_count = count->second;
      }
      channel_topic_[id] = merge_topic(topics_, topic, path_);
    }
    if (!statistics) count_messages();
  }

  const std::vector<TopicInfo>& topics() const override { return topics_; }
  const std::filesystem::path& path() const override { return path_; }
  std::string storage_identifier() const override { return "mcap"; }
  bool is_complete() const override { return complete_; }

  void select(const std::unordered_set<std::string>& topics, std::int64_t start_ns,
              std::int64_t end_ns) override {
    mcap::ReadMessageOptions options;
    options.startTime = static_cast<mcap::Timestamp>(std::max<std::int64_t>(start_ns, 0));
    options.endTime = static_cast<mcap::Timestamp>(std::max<std::int64_t>(end_ns, 0));
    if (end_ns == std::numeric_limits<std::int64_t>::max()) options.endTime = mcap::MaxTime;
    if (!topics.empty()) {
      options.topicFilter = [topics](std::string_view name) {
        return topics.count(std::string(name)) > 0;
      };
    }
    // Time order needs the chunk and message indexes; a file without them (a recording that
    // was cut off) is read in file order, which is the order the recorder wrote.
    const auto& chunks = reader_.chunkIndexes();
    const bool indexed = std::any_of(chunks.begin(), chunks.end(), [](const mcap::ChunkIndex& c) {
      return c.messageIndexLength > 0;
    });
    options.readOrder = indexed ? mcap::ReadMessageOptions::ReadOrder::LogTimeOrder
                                : mcap::ReadMessageOptions::ReadOrder::FileOrder;
    view_.emplace(reader_.readMessages(
        [this](const mcap::Status& problem) { note_problem(problem); }, options));
  }

  bool next(StoredMessage& out) override {
    if (!view_)
      select({}, std::numeric_limits<std::int64_t>::min(),
             std::numeric_limits<std::int64_t>::max());
    if (!it_) {
      it_.emplace(view_->begin());
    } else {
      ++*it_;
    }
    throw_problem();
    if (*it_ == view_->end()) return false;
    const mcap::Message& message = (*it_)->message;
    if (message.logTime > mcap::Timestamp(std::numeric_limits<std::int64_t>::max())) {
      fail("message log time " + std::to_string(message.logTime) +
           " ns is past the year 2262 (int64 nanoseconds)");
    }
    const auto topic = channel_topic_.find(message.channelId);
    if (topic == channel_topic_.end()) {
      fail("message refers to channel " + std::to_string(message.channelId) +
           ", which the file does not define");
    }
    out.topic = topic->second;
    out.log_time_ns = static_cast<std::int64_t>(message.logTime);
    out.data = reinterpret_cast<const std::uint8_t*>(message.data);
    out.size = message.dataSize;
    return true;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw core::Error(path_.string(), what); }

  void note_problem(const mcap::Status& problem) {
    if (problem_.empty()) problem_ = problem.message;
  }
  void throw_problem() {
    if (!problem_.empty()) fail("MCAP file is damaged: " + problem_);
  }

  // Files without a Statistics record (no summary section): one pass over the messages.
  void count_messages() {
    auto view =
        reader_.readMessages([this](const mcap::Status& problem) { note_problem(problem); });
    for (auto it = view.begin(); it != view.end(); ++it) {
      throw_problem();
      const auto topic = channel_topic_.find(it->message.channelId);
      if (topic != channel_topic_.end()) ++topics_[topic->second].message_count;
    }
    throw_problem();
  }

  std::filesystem::path path_;
  mcap::McapReader reader_;
  std::string problem_;  // the first problem the mcap library reported
  bool complete_ = true;
  std::vector<TopicInfo> topics_;
  std::unordered_map<mcap::ChannelId, std::size_t> channel_topic_;
  std::optional<mcap::LinearMessageView> view_;
  std::optional<mcap::LinearMessageView::Iterator> it_;
};

}  // namespace

std::unique_ptr<StorageFile> open_mcap_file(const std::filesystem::path& path) {
  return std::make_unique<McapFile>(path);
}

}  // namespace rgbdt::bag::detail
