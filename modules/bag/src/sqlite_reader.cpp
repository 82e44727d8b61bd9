// ROS 2 sqlite3 bags (.db3), through Debian's libsqlite3. rosbag2's schema: table `topics`
// (id, name, type, serialization_format, ...) and table `messages` (id, topic_id, timestamp,
// data), with an index on timestamp in every rosbag2 release, so reading in time order streams.
#include <sqlite3.h>

#include <limits>
#include <unordered_map>

#include "rgbdt/core/error.hpp"
#include "storage.hpp"

namespace rgbdt::bag::detail {
namespace {

// The path as an SQLite URI (https://www.sqlite.org/uri.html): characters with a meaning in
// URIs are percent-encoded.
std::string uri_path(const std::string& path) {
  std::string out;
  for (const unsigned char c : path) {
    if (c == '%' || c == '?' || c == '#' || c < 0x20 || c >= 0x7f) {
      const char* digits = "0123456789ABCDEF";
      out += '%';
      out += digits[c >> 4];
      out += digits[c & 15];
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

struct CloseDatabase {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};
struct FinalizeStatement {
  void operator()(sqlite3_stmt* statement) const { sqlite3_finalize(statement); }
};
using Statement = std::unique_ptr<sqlite3_stmt, FinalizeStatement>;

class SqliteFile : public StorageFile {
 public:
  explicit SqliteFile(const std::filesystem::path& path) : path_(path) {
    // A finished bag has no -wal file beside it; `immutable` then lets SQLite read it without
    // the lock files it would otherwise create, so bags in read-only folders open.
    std::filesystem::path wal = path;
    wal += "-wal";
    std::error_code ec;
    const bool recording = std::filesystem::exists(wal, ec);
    const std::string uri =
        "file:" + uri_path(path.string()) + (recording ? "?mode=ro" : "?mode=ro&immutable=1");
    sqlite3* db = nullptr;
    const int rc =
        sqlite3_open_v2(uri.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
    db_.reset(db);
    if (rc != SQLITE_OK) {
      fail("cannot open as an sqlite3 database: " +
           std::string(db ? sqlite3_errmsg(db) : "out of memory"));
    }
    read_topics();
  }

  const std::vector<TopicInfo>& topics() const override { return topics_; }
  const std::filesystem::path& path() const override { return path_; }
  std::string storage_identifier() const override { return "sqlite3"; }

  void select(const std::unordered_set<std::string>& topics, std::int64_t start_ns,
              std::int64_t end_ns) override {
    std::string sql =
        "SELECT topic_id, timestamp, data FROM messages WHERE timestamp >= ?1 AND timestamp < ?2";
    if (!topics.empty()) {
      std::string ids;
      for (const auto& [id, index] : id_topic_) {
        if (!topics.count(topics_[index].name)) continue;
        ids += (ids.empty() ? "" : ",") + std::to_string(id);
      }
      sql += " AND topic_id IN (" + ids + ")";
    }
    sql += " ORDER BY timestamp, id";
    messages_ = prepare(sql);
    sqlite3_bind_int64(messages_.get(), 1, start_ns);
    sqlite3_bind_int64(messages_.get(), 2, end_ns);
  }

  bool next(StoredMessage& out) override {
    if (!messages_)
      select({}, std::numeric_limits<std::int64_t>::min(),
             std::numeric_limits<std::int64_t>::max());
    const int rc = sqlite3_step(messages_.get());
    if (rc == SQLITE_DONE) return false;
    if (rc != SQLITE_ROW)
      fail("cannot read table 'messages': " + std::string(sqlite3_errmsg(db_.get())));
    const std::int64_t topic_id = sqlite3_column_int64(messages_.get(), 0);
    const auto topic = id_topic_.find(topic_id);
    if (topic == id_topic_.end()) {
      fail("a message has topic_id " + std::to_string(topic_id) +
           ", which table 'topics' does not hold");
    }
    out.topic = topic->second;
    out.log_time_ns = sqlite3_column_int64(messages_.get(), 1);
    // The blob pointer stays valid until the next sqlite3_step.
    out.data = static_cast<const std::uint8_t*>(sqlite3_column_blob(messages_.get(), 2));
    out.size = static_cast<std::size_t>(sqlite3_column_bytes(messages_.get(), 2));
    return true;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw core::Error(path_.string(), what); }

  Statement prepare(const std::string& sql) {
    sqlite3_stmt* statement = nullptr;
    const int rc = sqlite3_prepare_v2(db_.get(), sql.c_str(), -1, &statement, nullptr);
    Statement owned(statement);
    if (rc != SQLITE_OK) {
      fail("not a rosbag2 sqlite3 bag (" + std::string(sqlite3_errmsg(db_.get())) + " in `" + sql +
           "`)");
    }
    return owned;
  }

  void read_topics() {
    const Statement topics =
        prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY name, id");
    int rc;
    while ((rc = sqlite3_step(topics.get())) == SQLITE_ROW) {
      TopicInfo topic;
      const auto text = [&](int column) {
        const unsigned char* value = sqlite3_column_text(topics.get(), column);
        return value ? std::string(reinterpret_cast<const char*>(value)) : std::string();
      };
      topic.name = text(1);
      topic.type = text(2);
      topic.serialization_format = text(3);
      id_topic_[sqlite3_column_int64(topics.get(), 0)] = merge_topic(topics_, topic, path_);
    }
    if (rc != SQLITE_DONE)
      fail("cannot read table 'topics': " + std::string(sqlite3_errmsg(db_.get())));
    // One pass over the messages (no index holds topic_id).
    const Statement counts = prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id");
    while ((rc = sqlite3_step(counts.get())) == SQLITE_ROW) {
      const std::int64_t topic_id = sqlite3_column_int64(counts.get(), 0);
      const auto topic = id_topic_.find(topic_id);
      if (topic == id_topic_.end()) {
        fail("messages have topic_id " + std::to_string(topic_id) +
             ", which table 'topics' does not hold");
      }
      topics_[topic->second].message_count +=
          static_cast<std::uint64_t>(sqlite3_column_int64(counts.get(), 1));
    }
    if (rc != SQLITE_DONE)
      fail("cannot read table 'messages': " + std::string(sqlite3_errmsg(db_.get())));
  }

  std::filesystem::path path_;
  std::unique_ptr<sqlite3, CloseDatabase> db_;
  Statement messages_;  // declared after db_: finalized before the database closes
  std::vector<TopicInfo> topics_;
  std::unordered_map<std::int64_t, std::size_t> id_topic_;  // topics.id -> index in topics_
};

}  // namespace

std::unique_ptr<StorageFile> open_sqlite_file(const std::filesystem::path& path) {
  return std::make_unique<SqliteFile>(path);
}

}  // namespace rgbdt::bag::detail
