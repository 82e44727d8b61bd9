#pragma once
/// \file
/// Time-stamped file indexes (CSV "time_s,file" with a header line), as used by mapping
/// sessions for clouds and camera frames, and nearest-in-time look-up.
#include <string>
#include <vector>

namespace rgbdt::core {

struct TimedFile {
  double time_s = 0.0;  ///< seconds on the session clock
  std::string file;     ///< absolute path once read
};

/// Reads an index; relative file names are resolved against the CSV's folder. Times are
/// parsed whole-field (rgbdt/core/parse.hpp: "100.802xyz", "0x64", "nan" are errors), file
/// names are trimmed, rows must be sorted by time (non-decreasing). An index with only its
/// header is valid and returns no rows (callers that need rows say so). Throws
/// rgbdt::core::Error naming the file, the line, the field and what was expected; a file
/// whose first line is neither the header nor a row is refused without quoting it.
std::vector<TimedFile> read_time_index(const std::string& csv_path);
/// Parses index text as if read from csv_path (which need not exist).
std::vector<TimedFile> parse_time_index(const std::string& text, const std::string& csv_path);
/// Writes an index atomically (rgbdt/core/output.hpp). Relative entry paths are relative
/// to the working directory (as paths given on a command line); files below the CSV's
/// folder are written relative to it, so `--out rel/dir` works. Throws
/// std::invalid_argument for a non-finite time or a file name with a line break, and
/// rgbdt::core::Error naming the path when writing fails.
void write_time_index(const std::string& csv_path, const std::vector<TimedFile>& entries);

/// Index of the entry nearest to t in a time-sorted vector; -1 if the vector is empty.
int nearest_in_time(const std::vector<TimedFile>& entries, double t);

}  // namespace rgbdt::core
