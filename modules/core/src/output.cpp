#include "rgbdt/core/output.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <climits>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "rgbdt/core/error.hpp"

namespace fs = std::filesystem;

namespace rgbdt::core {
namespace {

// A sibling name that differs between processes and between calls, keeps the extension
// and is hidden, so a listing of the output folder shows only finished files.
std::string temp_sibling(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(path);
  const std::string stem = p.stem().string();
  const std::string name = "." + stem + ".tmp" + std::to_string(::getpid()) + "_" +
                           std::to_string(counter++) + p.extension().string();
  return (p.parent_path() / name).string();
}

std::string errno_text() { return std::strerror(errno); }

// The temporaries being written, in fixed storage a signal handler can read: a slot is
// claimed (kFree -> kFilling), filled, published (kLive) and released (kFree).
constexpr int kFree = 0;
constexpr int kFilling = 1;
constexpr int kLive = 2;
struct TempSlot {
  std::atomic<int> state{kFree};
  char path[PATH_MAX];
};
std::array<TempSlot, 64> g_temps;
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads slot states");

// Tracks `path` while it exists; returns its slot, or -1 when the path is too long or 64
// temporaries are tracked already (the write itself goes on untracked).
int track_temp(const std::string& path) {
  if (path.size() >= PATH_MAX) return -1;
  for (std::size_t i = 0; i < g_temps.size(); ++i) {
    int expected = kFree;
    if (g_temps[i].state.compare_exchange_strong(expected, kFilling)) {
      std::memcpy(g_temps[i].path, path.c_str(), path.size() + 1);
      g_temps[i].state.store(kLive);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void untrack_temp(int slot) {
  if (slot >= 0) g_temps[static_cast<std::size_t>(slot)].state.store(kFree);
}

class TrackedTemp {
 public:
  explicit TrackedTemp(const std::string& path) : slot_(track_temp(path)) {}
  ~TrackedTemp() { untrack_temp(slot_); }
  TrackedTemp(const TrackedTemp&) = delete;
  TrackedTemp& operator=(const TrackedTemp&) = delete;

 private:
  int slot_;
};

}  // namespace

void write_file_atomic(const std::string& path, std::string_view content) {
  const std::string tmp = temp_sibling(path);
  const TrackedTemp tracked(tmp);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(path, "cannot open for writing: " + errno_text());
  const char* p = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = errno_text();
      ::close(fd);
      ::unlink(tmp.c_str());
      throw Error(path, "write failed (" + why + "); nothing was written");
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
    const std::string why = errno_text();
    ::close(fd);
    ::unlink(tmp.c_str());
    throw Error(path, "write failed (" + why + "); nothing was written");
  }
  if (::close(fd) != 0) {
    const std::string why = errno_text();
    ::unlink(tmp.c_str());
    throw Error(path, "close failed (" + why + "); nothing was written");
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = errno_text();
    ::unlink(tmp.c_str());
    throw Error(path, "cannot rename the finished file into place: " + why);
  }
}

TempOutput::TempOutput(std::string path)
    : path_(std::move(path)), temp_(temp_sibling(path_)), slot_(track_temp(temp_)) {}

TempOutput::~TempOutput() {
  if (!committed_) ::unlink(temp_.c_str());
  untrack_temp(slot_);
}

void TempOutput::commit() {
  std::error_code ec;
  const auto size = fs::file_size(temp_, ec);
  if (ec || size == 0) {
    ::unlink(temp_.c_str());
    throw Error(path_, "the writer produced no data (disk full or folder not writable?)");
  }
  // Flush the library's data to disk before the rename makes it visible under its name.
  const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    const bool synced = ::fsync(fd) == 0 || errno == EINVAL || errno == EROFS;
    const std::string why = errno_text();
    ::close(fd);
    if (!synced) {
      ::unlink(temp_.c_str());
      throw Error(path_, "write failed (" + why + "); nothing was written");
    }
  }
  if (::rename(temp_.c_str(), path_.c_str()) != 0) {
    const std::string why = errno_text();
    ::unlink(temp_.c_str());
    throw Error(path_, "cannot rename the finished file into place: " + why);
  }
  committed_ = true;
  untrack_temp(slot_);
  slot_ = -1;
}

void remove_unfinished_outputs() noexcept {
  for (TempSlot& s : g_temps) {
    if (s.state.load() == kLive) ::unlink(s.path);
  }
}

void remove_stale_output(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(path, ec))) return;
  fs::remove(path, ec);
  if (ec) throw Error(path, "cannot remove the output of an earlier run: " + ec.message());
}

}  // namespace rgbdt::core
