#include "rgbdt/core/time_index.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <optional>
#include <string_view>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/parse.hpp"

namespace fs = std::filesystem;

namespace rgbdt::core {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// A field as printed in errors: short and printable only.
std::string shown(std::string_view field) {
  std::string out;
  for (const char ch : field.substr(0, 40)) {
    const auto c = static_cast<unsigned char>(ch);
    out += (c >= 0x20 && c < 0x7f) ? ch : '?';
  }
  return "'" + out + (field.size() > 40 ? "...'" : "'");
}

}  // namespace

std::vector<TimedFile> parse_time_index(const std::string& text, const std::string& csv_path) {
  const fs::path dir = fs::absolute(fs::path(csv_path)).parent_path();
  std::vector<TimedFile> out;
  std::size_t start = 0;
  int line_no = 0;
  bool first_content = true;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string_view line = trim(std::string_view(text).substr(start, end - start));
    start = end + 1;
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    const bool first = first_content;
    first_content = false;
    if (first && line.rfind("time", 0) == 0) continue;  // header
    const std::string where = "line " + std::to_string(line_no) + ": ";
    const auto comma = line.find(',');
    const std::optional<double> time =
        comma == std::string_view::npos ? std::nullopt : parse_finite_double(line.substr(0, comma));
    if (first && !time) {
      // Not an index at all (perhaps another kind of file): its content is not quoted.
      throw Error(csv_path, where + "expected the header 'time_s,file' or a row 'time_s,file' (a CSV time index)");
    }
    if (comma == std::string_view::npos) throw Error(csv_path, where + "expected 'time_s,file'");
    if (!time) {
      throw Error(csv_path, where + "time_s " + shown(trim(line.substr(0, comma))) +
                                ", expected a finite number of seconds written in full");
    }
    const std::string_view file = trim(line.substr(comma + 1));
    if (file.empty()) throw Error(csv_path, where + "empty file name, expected 'time_s,file'");
    if (!out.empty() && *time < out.back().time_s) {
      throw Error(csv_path, where + "time " + shown(trim(line.substr(0, comma))) +
                                " is earlier than the previous row (expected sorted times)");
    }
    const fs::path p{std::string(file)};
    out.push_back({*time, (p.is_absolute() ? p : dir / p).lexically_normal().string()});
  }
  return out;
}

std::vector<TimedFile> read_time_index(const std::string& csv_path) {
  std::ifstream in(csv_path, std::ios::binary);
  std::error_code ec;
  if (fs::is_directory(csv_path, ec)) throw Error(csv_path, "is a folder, expected a CSV time index file");
  if (!in) throw Error(csv_path, "cannot open time index for reading");
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw Error(csv_path, "read failed");
  return parse_time_index(ss.str(), csv_path);
}

void write_time_index(const std::string& csv_path, const std::vector<TimedFile>& entries) {
  if (csv_path.empty()) throw std::invalid_argument("write_time_index: empty index path");
  const fs::path dir = fs::absolute(fs::path(csv_path)).parent_path();
  std::ostringstream out;
  out << "time_s,file\n" << std::setprecision(17);
  for (const auto& e : entries) {
    if (!std::isfinite(e.time_s) || e.file.empty() || e.file.find_first_of("\r\n") != std::string::npos) {
      throw std::invalid_argument("cannot write " + csv_path + ": entry '" + e.file + "' at time " +
                                  std::to_string(e.time_s) +
                                  " (expected a finite time and a file name without line breaks)");
    }
    // Relative entries are relative to the working directory, as paths given to apps are;
    // rows are written relative to the index's folder, where the reader resolves them.
    const fs::path p = fs::absolute(fs::path(e.file)).lexically_normal();
    fs::path row = p;
    const fs::path rel = p.lexically_relative(dir);
    if (!rel.empty() && *rel.begin() != "..") row = rel;
    out << e.time_s << ',' << row.string() << '\n';
  }
  write_file_atomic(csv_path, out.str());
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
