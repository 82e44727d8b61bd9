#pragma once
/// \file
/// Writing result files so that a reader never sees half of one: every file is written to
/// a temporary sibling, every write and the close are checked, and only then is it renamed
/// over the final name (atomic on POSIX file systems). A run that fails or is interrupted
/// leaves either the whole file or none.
#include <string>
#include <string_view>

namespace rgbdt::core {

/// Writes `content` to `path` atomically. Throws rgbdt::core::Error naming `path` when any
/// step fails (open, write, flush, close, rename); the temporary file is then removed.
void write_file_atomic(const std::string& path, std::string_view content);

/// For files written by a library that takes a path (cv::imwrite, PCL, OctoMap): hand
/// temp_path() to the library, then call commit(). A TempOutput destroyed without commit()
/// removes its temporary file, so an exception leaves nothing behind.
class TempOutput {
 public:
  explicit TempOutput(std::string path);
  ~TempOutput();
  TempOutput(const TempOutput&) = delete;
  TempOutput& operator=(const TempOutput&) = delete;

  /// Where the library writes; it keeps the final name's extension (libraries pick the
  /// format from it).
  const std::string& temp_path() const { return temp_; }
  const std::string& path() const { return path_; }

  /// Checks the temporary file exists and is not empty, then renames it into place.
  /// Throws rgbdt::core::Error naming the final path otherwise.
  void commit();

 private:
  std::string path_;
  std::string temp_;
  int slot_ = -1;  // where remove_unfinished_outputs() finds temp_
  bool committed_ = false;
};

/// Removes every temporary file that write_file_atomic or a TempOutput is writing at this
/// moment. Async-signal-safe: the interrupt handler calls it before a second Ctrl-C ends
/// the process, so no hidden temporary is left behind. (Up to 64 temporaries at a time are
/// tracked, paths up to PATH_MAX.)
void remove_unfinished_outputs() noexcept;

/// Removes `path` if it exists (a stale output of an earlier run); throws naming it when it
/// exists and cannot be removed.
void remove_stale_output(const std::string& path);

}  // namespace rgbdt::core
