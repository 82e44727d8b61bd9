#include "rgbdt/core/time_index.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"

namespace fs = std::filesystem;

namespace rgbdt::core {

std::vector<TimedFile> read_time_index(const std::string& csv_path) {
  std::ifstream in(csv_path);
  if (!in) throw Error(csv_path, "cannot open time index for reading");
  const fs::path dir = fs::absolute(fs::path(csv_path)).parent_path();
  std::vector<TimedFile> out;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (line_no == 1 && line.rfind("time", 0) == 0) continue;  // header
    const auto comma = line.find(',');
    if (comma == std::string::npos) {
      throw Error(csv_path, "line " + std::to_string(line_no) + ": '" + line +
                                "' expected 'time_s,file'");
    }
    TimedFile entry;
    const std::string time_text = line.substr(0, comma);
    char* end = nullptr;
    entry.time_s = std::strtod(time_text.c_str(), &end);
    if (end == time_text.c_str() || !std::isfinite(entry.time_s)) {
      throw Error(csv_path, "line " + std::to_string(line_no) + ": time '" + time_text +
                                "' expected a number of seconds");
    }
    std::string file = line.substr(comma + 1);
    file.erase(0, file.find_first_not_of(" \t"));
    if (file.empty()) {
      throw Error(csv_path, "line " + std::to_string(line_no) + ": empty file name");
    }
    const fs::path p(file);
    entry.file = (p.is_absolute() ? p : dir / p).lexically_normal().string();
    if (!out.empty() && entry.time_s < out.back().time_s) {
      throw Error(csv_path, "line " + std::to_string(line_no) + ": time " + time_text +
                                " is earlier than the previous row (expected sorted times)");
    }
    out.push_back(std::move(entry));
  }
  return out;
}

void write_time_index(const std::string& csv_path, const std::vector<TimedFile>& entries) {
  std::ofstream out(csv_path);
  if (!out) throw Error(csv_path, "cannot open file for writing");
  const fs::path dir = fs::absolute(fs::path(csv_path)).parent_path();
  out << "time_s,file\n" << std::setprecision(15);
  for (const auto& e : entries) {
    fs::path p(e.file);
    if (p.is_absolute()) {
      const fs::path rel = p.lexically_relative(dir);
      if (!rel.empty() && *rel.begin() != "..") p = rel;
    }
    out << e.time_s << ',' << p.string() << '\n';
  }
  if (!out) throw Error(csv_path, "write failed");
}

int nearest_in_time(const std::vector<TimedFile>& entries, double t) {
  if (entries.empty()) return -1;
  const auto it = std::lower_bound(entries.begin(), entries.end(), t,
                                   [](const TimedFile& e, double v) { return e.time_s < v; });
  if (it == entries.begin()) return 0;
  if (it == entries.end()) return static_cast<int>(entries.size()) - 1;
  const auto prev = it - 1;
  return static_cast<int>((t - prev->time_s <= it->time_s - t) ? prev - entries.begin()
                                                               : it - entries.begin());
}

}  // namespace rgbdt::core
