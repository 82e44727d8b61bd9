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

/// Reads an index; relative file names are resolved against the CSV's folder. Rows must
/// be sorted by time (non-decreasing). Throws rgbdt::core::Error naming the file and line.
std::vector<TimedFile> read_time_index(const std::string& csv_path);
/// Writes an index; files below the CSV's folder are written relative to it.
void write_time_index(const std::string& csv_path, const std::vector<TimedFile>& entries);

/// Index of the entry nearest to t in a time-sorted vector; -1 if the vector is empty.
int nearest_in_time(const std::vector<TimedFile>& entries, double t);

}  // namespace rgbdt::core
