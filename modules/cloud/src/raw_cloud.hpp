#pragma once
// The decoded body of a point-cloud file (PCD or PLY) before it becomes a LoadedCloud:
// interleaved records of `point_step` bytes, one per point, with the fields the header
// declared. The file readers fill it only after checking the header against the file's
// size; to_loaded_cloud() then checks the values (finite times, ring range) and converts.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rgbdt/cloud/pcd_io.hpp"

namespace rgbdt::cloud::detail {

enum class Kind { kInt, kUint, kFloat };

struct RawField {
  std::string name;
  Kind kind = Kind::kFloat;
  std::size_t size = 4;    // bytes per element: 1, 2, 4 or 8
  std::size_t count = 1;   // elements per point
  std::size_t offset = 0;  // within a record
};

struct RawCloud {
  std::vector<RawField> fields;
  std::size_t point_step = 0;
  std::size_t points = 0;
  /// points * point_step bytes, native byte order. Either owned (`storage`) or a view into
  /// the file's bytes held by the caller.
  std::vector<std::uint8_t> storage;
  const std::uint8_t* data = nullptr;
};

/// Upper bounds shared by the readers. A header longer than kMaxHeaderBytes is not a header;
/// a record wider than kMaxPointStep or a body larger than kMaxBodyBytes is refused before
/// anything is allocated for it.
constexpr std::size_t kMaxHeaderBytes = 64 * 1024;
constexpr std::size_t kMaxPointStep = 64 * 1024;
constexpr std::size_t kMaxFields = 256;
constexpr std::uint64_t kMaxBodyBytes = std::uint64_t{1} << 30;

/// Largest |t| accepted, in seconds from the cloud's first point (kMaxRing, the largest
/// ring, is in rgbdt/cloud/point_types.hpp).
constexpr double kMaxRelativeTime = 3600.0;

/// The lines of a text header at the start of a file's bytes, one at a time, without their
/// line ending ("\n" or "\r\n"). `format` ("PCD", "PLY") and `terminator` (the line that
/// ends the header, as an error message names it) only word the errors.
class HeaderLines {
 public:
  HeaderLines(const std::string& bytes, const std::string& path, std::string format,
              std::string terminator)
      : bytes_(bytes), path_(path), format_(std::move(format)), terminator_(std::move(terminator)) {}

  /// The next line. Throws naming the file when the bytes end before the terminator or
  /// the line reaches past kMaxHeaderBytes (a binary file, not a header).
  std::string_view next();
  /// 1-based number of the line next() returned last.
  int line_no() const { return line_no_; }
  /// The offset of the first byte after the line next() returned last.
  std::size_t end() const { return pos_ < bytes_.size() ? pos_ : bytes_.size(); }

 private:
  const std::string& bytes_;
  const std::string& path_;
  std::string format_;
  std::string terminator_;
  std::size_t pos_ = 0;
  int line_no_ = 0;
};

/// `line` split at runs of spaces and tabs.
std::vector<std::string_view> split_tokens(std::string_view line);

/// The whole file; throws naming it when it is missing, not a regular file or unreadable.
std::string read_whole_file(const std::string& path, const char* what);

/// `text` quoted for an error message: at most 40 characters, non-printable bytes as \xNN.
std::string quote(std::string_view text);

/// A number as an error message shows it, with up to `digits` significant digits.
std::string show(double value, int digits = 10);

/// Lower case without a "scalar_" prefix (CloudCompare names exported scalar fields so).
std::string normalized_name(std::string_view name);

/// Parses one ASCII value of the given kind and size into `out` (native byte order).
/// Floats accept nan/inf spellings (PCL writes "nan" for missing returns); integers must be
/// whole numbers within the type's range. Returns false when `token` is not such a value.
bool parse_ascii_value(std::string_view token, Kind kind, std::size_t size, std::uint8_t* out);

/// Checks the values and converts: x y z required; intensity, ring and t optional (by
/// alias); points with non-finite x y z dropped; t finite and within kMaxRelativeTime of the
/// earliest point; ring an integer in 0..kMaxRing; intensity finite. Errors name `path`,
/// the point index in the file and the value.
LoadedCloud to_loaded_cloud(const RawCloud& raw, const std::string& path, const char* format);

}  // namespace rgbdt::cloud::detail
