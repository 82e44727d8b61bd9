// ROS 2 MCAP files through the vendored mcap library (third_party/mcap).
#include <mcap/reader.hpp>

#include <algorithm>
#include <limits>
#include <optional>
#include <unordered_map>

#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag::detail {
namespace {

class McapFile : public StorageFile {
 public:
  explicit McapFile(const std::filesystem::path& path) : path_(path) {
    const mcap::Status opened = reader_.open(path.string());
    if (!opened.ok()) fail("cannot open as MCAP: " + opened.message);
    // A file without its summary and footer (the recorder did not close it) is scanned up to
    // the last intact record.
    complete_ = reader_.readSummary(mcap::ReadSummaryMethod::NoFallbackScan).ok();
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
