#include "rgbdt/cloud/pcd_io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/io/lzf.h>
#include <pcl/io/pcd_io.h>

#include <cstring>
#include <map>
#include <optional>
#include <vector>

#include "raw_cloud.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/parse.hpp"

namespace rgbdt::cloud {
namespace {

using detail::Kind;
using detail::quote;
using detail::RawCloud;
using detail::RawField;

// LZF encodes at most 264 output bytes in a 3-byte back reference, so no valid stream
// expands more than 88 times.
constexpr std::uint64_t kMaxLzfExpansion = 88;

enum class DataFormat { kAscii, kBinary, kBinaryCompressed };

struct PcdHeader {
  std::vector<RawField> fields;
  std::size_t point_step = 0;
  std::uint64_t points = 0;
  DataFormat data = DataFormat::kAscii;
  std::size_t data_offset = 0;  // first byte after the DATA line
};

std::string join(const std::vector<std::string_view>& tokens) {
  std::string out;
  for (const auto& t : tokens) out += (out.empty() ? "" : " ") + std::string(t);
  return out;
}

// A PCD header's values by keyword (COLUMNS read as FIELDS).
using HeaderValues = std::map<std::string, std::vector<std::string_view>>;

// The header's lines up to and including DATA: each keyword known and given once, with a
// value; *data_offset is the first byte after the DATA line.
HeaderValues read_header_lines(const std::string& bytes, const std::string& path,
                               std::size_t* data_offset) {
  HeaderValues values;
  detail::HeaderLines lines(bytes, path, "PCD", "a DATA line");
  bool have_data = false;
  while (!have_data) {
    const std::string_view line = lines.next();
    const int line_no = lines.line_no();
    const auto tokens = detail::split_tokens(line);
    if (tokens.empty() || tokens[0][0] == '#') continue;
    std::string key(tokens[0]);
    if (key == "COLUMNS") key = "FIELDS";  // PCD 0.5
    static const char* kKeys[] = {"VERSION", "FIELDS", "SIZE",      "TYPE",   "COUNT",
                                  "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
    if (std::find(std::begin(kKeys), std::end(kKeys), key) == std::end(kKeys)) {
      throw core::Error(path, "PCD header line " + std::to_string(line_no) + " starts with " +
                                  quote(tokens[0]) +
                                  ", expected one of VERSION FIELDS SIZE TYPE COUNT WIDTH HEIGHT "
                                  "VIEWPOINT POINTS DATA");
    }
    if (values.count(key)) {
      throw core::Error(path,
                        "PCD header repeats " + key + " (line " + std::to_string(line_no) + ")");
    }
    if (tokens.size() < 2) {
      throw core::Error(
          path, "PCD header " + key + " has no value (line " + std::to_string(line_no) + ")");
    }
    values[key] = {tokens.begin() + 1, tokens.end()};
    if (key == "DATA") have_data = true;
  }
  *data_offset = lines.end();
  return values;
}

// One field of FIELDS/SIZE/TYPE/COUNT at byte `offset` of the point.
RawField parse_field(std::string_view name, std::string_view size_text, std::string_view type,
                     std::string_view count_text, std::size_t offset, const std::string& path) {
  RawField f;
  f.name = std::string(name);
  const auto size = core::parse_integer(size_text, 1, 8);
  if (!size || (*size != 1 && *size != 2 && *size != 4 && *size != 8)) {
    throw core::Error(
        path, "PCD field " + f.name + " has SIZE " + quote(size_text) + ", expected 1, 2, 4 or 8");
  }
  f.size = static_cast<std::size_t>(*size);
  if (type == "F") {
    f.kind = Kind::kFloat;
    if (f.size != 4 && f.size != 8) {
      throw core::Error(path, "PCD field " + f.name + " has TYPE F with SIZE " +
                                  std::to_string(f.size) + ", expected SIZE 4 or 8 for floats");
    }
  } else if (type == "U") {
    f.kind = Kind::kUint;
  } else if (type == "I") {
    f.kind = Kind::kInt;
  } else {
    throw core::Error(path,
                      "PCD field " + f.name + " has TYPE " + quote(type) + ", expected F, U or I");
  }
  const auto count =
      core::parse_integer(count_text, 1, static_cast<long long>(detail::kMaxPointStep));
  if (!count) {
    throw core::Error(path, "PCD field " + f.name + " has COUNT " + quote(count_text) +
                                ", expected a whole number from 1 to " +
                                std::to_string(detail::kMaxPointStep));
  }
  f.count = static_cast<std::size_t>(*count);
  f.offset = offset;
  return f;
}

// h->fields and h->point_step from FIELDS, SIZE, TYPE and COUNT (one value per field each).
void parse_fields(const HeaderValues& values, const std::string& path, PcdHeader* h) {
  const auto& names = values.at("FIELDS");
  const auto& sizes = values.at("SIZE");
  const auto& types = values.at("TYPE");
  const std::size_t n_fields = names.size();
  if (n_fields > detail::kMaxFields) {
    throw core::Error(path, "PCD header has " + std::to_string(n_fields) +
                                " FIELDS, expected at most " + std::to_string(detail::kMaxFields));
  }
  std::vector<std::string_view> counts =
      values.count("COUNT") ? values.at("COUNT") : std::vector<std::string_view>(n_fields, "1");
  for (const auto& [key, list] :
       {std::pair<const char*, const std::vector<std::string_view>*>{"SIZE", &sizes},
        {"TYPE", &types},
        {"COUNT", &counts}}) {
    if (list->size() != n_fields) {
      throw core::Error(path, std::string("PCD header has ") + std::to_string(n_fields) +
                                  " FIELDS (" + join(names) + ") but " +
                                  std::to_string(list->size()) + " " + key + " values (" +
                                  join(*list) + "), expected one per field");
    }
  }
  std::size_t offset = 0;
  for (std::size_t k = 0; k < n_fields; ++k) {
    RawField f = parse_field(names[k], sizes[k], types[k], counts[k], offset, path);
    offset += f.size * f.count;
    if (offset > detail::kMaxPointStep) {
      throw core::Error(path, "PCD point is wider than " + std::to_string(detail::kMaxPointStep) +
                                  " bytes (SIZE x COUNT summed over FIELDS)");
    }
    h->fields.push_back(std::move(f));
  }
  h->point_step = offset;
}

// A header value that is a whole number from 0 to 2^32 - 1.
std::uint64_t whole(const char* key, std::string_view text, const std::string& path) {
  const auto v = core::parse_integer(text, 0, 0xffffffffLL);
  if (!v) {
    throw core::Error(path, std::string("PCD header ") + key + " is " + quote(text) +
                                ", expected a whole number from 0 to 4294967295");
  }
  return static_cast<std::uint64_t>(*v);
}

// The one value of a keyword; none when the header has no such line.
std::optional<std::string_view> single(const HeaderValues& values, const char* key,
                                       const std::string& path) {
  if (!values.count(key)) return std::nullopt;
  const auto& list = values.at(key);
  if (list.size() != 1) {
    throw core::Error(path, std::string("PCD header ") + key + " has " +
                                std::to_string(list.size()) + " values (" + join(list) +
                                "), expected one");
  }
  return list[0];
}

// WIDTH x HEIGHT, checked against POINTS when given and against 2^32 - 1.
std::uint64_t point_count(const HeaderValues& values, const std::string& path) {
  const std::uint64_t width = whole("WIDTH", *single(values, "WIDTH", path), path);
  const std::uint64_t height =
      values.count("HEIGHT") ? whole("HEIGHT", *single(values, "HEIGHT", path), path) : 1;
  const std::uint64_t points = width * height;
  if (const auto p = single(values, "POINTS", path)) {
    const std::uint64_t stated = whole("POINTS", *p, path);
    if (stated != points) {
      throw core::Error(path, "PCD header says POINTS " + std::to_string(stated) +
                                  " but WIDTH x HEIGHT = " + std::to_string(width) + " x " +
                                  std::to_string(height) + " = " + std::to_string(points) +
                                  ", expected them equal");
    }
  }
  if (points > 0xffffffffULL) {
    throw core::Error(path, "PCD header WIDTH x HEIGHT = " + std::to_string(points) +
                                " points, expected at most 4294967295");
  }
  return points;
}

void check_viewpoint(const HeaderValues& values, const std::string& path) {
  if (!values.count("VIEWPOINT")) return;
  const auto& vp = values.at("VIEWPOINT");
  bool ok = vp.size() == 7;
  for (const auto& v : vp) ok = ok && core::parse_finite_double(v).has_value();
  if (!ok) {
    throw core::Error(path, "PCD header VIEWPOINT is '" + join(vp) +
                                "', expected 7 finite numbers (tx ty tz qw qx qy qz)");
  }
}

DataFormat data_format(const HeaderValues& values, const std::string& path) {
  const auto data = *single(values, "DATA", path);
  if (data == "ascii") return DataFormat::kAscii;
  if (data == "binary") return DataFormat::kBinary;
  if (data == "binary_compressed") return DataFormat::kBinaryCompressed;
  throw core::Error(
      path, "PCD header DATA is " + quote(data) + ", expected ascii, binary or binary_compressed");
}

// Reads and checks the header: every keyword's values, the lengths of FIELDS/SIZE/TYPE/COUNT,
// WIDTH x HEIGHT == POINTS. Nothing is allocated from a header value here.
PcdHeader parse_header(const std::string& bytes, const std::string& path) {
  if (bytes.empty()) {
    throw core::Error(path,
                      "file is empty (0 bytes), expected a PCD header (VERSION, FIELDS, ...)");
  }
  PcdHeader h;
  const HeaderValues values = read_header_lines(bytes, path, &h.data_offset);
  for (const char* required : {"FIELDS", "SIZE", "TYPE", "WIDTH"}) {
    if (!values.count(required)) {
      throw core::Error(path, std::string("PCD header has no ") + required + " line");
    }
  }
  parse_fields(values, path, &h);
  h.points = point_count(values, path);
  check_viewpoint(values, path);
  h.data = data_format(values, path);
  return h;
}

std::uint32_t read_u32_le(const std::string& bytes, std::size_t at) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data() + at);
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

std::string points_times_step(const PcdHeader& h) {
  return std::to_string(h.points) + " points x " + std::to_string(h.point_step) +
         " bytes = " + std::to_string(h.points * h.point_step) + " bytes";
}

void decode_binary(const std::string& bytes, const PcdHeader& h, RawCloud& raw,
                   const std::string& path) {
  const std::uint64_t need = h.points * h.point_step;
  const std::uint64_t have = bytes.size() - h.data_offset;
  if (need > have) {
    throw core::Error(path, "DATA binary needs " + points_times_step(h) +
                                " after the header, the file holds " + std::to_string(have) +
                                " (truncated, or POINTS too large)");
  }
  raw.data = reinterpret_cast<const std::uint8_t*>(bytes.data() + h.data_offset);
}

void decode_compressed(const std::string& bytes, const PcdHeader& h, RawCloud& raw,
                       const std::string& path) {
  const std::uint64_t need = h.points * h.point_step;
  const std::uint64_t have = bytes.size() - h.data_offset;
  if (have < 8) {
    throw core::Error(
        path, "DATA binary_compressed needs 8 bytes of sizes after the header, the file holds " +
                  std::to_string(have));
  }
  const std::uint32_t compressed = read_u32_le(bytes, h.data_offset);
  const std::uint32_t uncompressed = read_u32_le(bytes, h.data_offset + 4);
  if (need == 0 && uncompressed == 0) return;  // an empty cloud
  if (compressed == 0) {
    throw core::Error(path, "binary_compressed PCD has compressed size 0, expected > 0 for " +
                                std::to_string(h.points) + " points");
  }
  if (compressed > have - 8) {
    throw core::Error(path, "binary_compressed PCD claims " + std::to_string(compressed) +
                                " compressed bytes, the file holds " + std::to_string(have - 8) +
                                " after the header (truncated or corrupt)");
  }
  if (uncompressed != need) {
    throw core::Error(path, "binary_compressed PCD has uncompressed size " +
                                std::to_string(uncompressed) + ", expected " +
                                points_times_step(h) + " from the header");
  }
  if (uncompressed > kMaxLzfExpansion * compressed) {
    throw core::Error(path, "binary_compressed PCD claims " + std::to_string(uncompressed) +
                                " uncompressed bytes from " + std::to_string(compressed) +
                                " compressed, expected at most " +
                                std::to_string(kMaxLzfExpansion) +
                                " times as many (LZF's largest expansion)");
  }
  if (uncompressed > detail::kMaxBodyBytes) {
    throw core::Error(path, "binary_compressed PCD has uncompressed size " +
                                std::to_string(uncompressed) + ", expected at most " +
                                std::to_string(detail::kMaxBodyBytes));
  }
  std::vector<std::uint8_t> planar(uncompressed);
  const unsigned int got =
      pcl::lzfDecompress(bytes.data() + h.data_offset + 8, compressed, planar.data(), uncompressed);
  if (got != uncompressed) {
    throw core::Error(path,
                      "binary_compressed PCD data decompresses to " +
                          (got == 0 ? std::string("an error") : std::to_string(got) + " bytes") +
                          ", expected " + std::to_string(uncompressed) + " (corrupt data)");
  }
  // The compressed body stores each field for all points, field after field; interleave.
  raw.storage.resize(uncompressed);
  std::size_t src = 0;
  for (const auto& f : h.fields) {
    const std::size_t width = f.size * f.count;
    for (std::size_t i = 0; i < h.points; ++i) {
      std::memcpy(raw.storage.data() + i * h.point_step + f.offset, planar.data() + src, width);
      src += width;
    }
  }
  raw.data = raw.storage.data();
}

void decode_ascii(const std::string& bytes, const PcdHeader& h, RawCloud& raw,
                  const std::string& path) {
  std::size_t per_point = 0;
  for (const auto& f : h.fields) per_point += f.count;
  const std::uint64_t have = bytes.size() - h.data_offset;
  // Each value takes at least one character and one separator.
  if (h.points * per_point * 2 > have + 1) {
    throw core::Error(path, "DATA ascii: POINTS " + std::to_string(h.points) + " with " +
                                std::to_string(per_point) + " values each need at least " +
                                std::to_string(h.points * per_point * 2) +
                                " bytes, the file holds " + std::to_string(have) +
                                " after the header");
  }
  raw.storage.assign(h.points * h.point_step, 0);
  raw.data = raw.storage.data();
  // Line numbers in messages count from the file's first line.
  std::size_t line_no = 1;
  for (std::size_t i = 0; i < h.data_offset; ++i) line_no += bytes[i] == '\n';
  std::size_t pos = h.data_offset;
  std::size_t point = 0;
  for (; pos < bytes.size(); ++line_no) {
    std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos) eol = bytes.size();
    std::string_view line(bytes.data() + pos, eol - pos);
    pos = eol + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const auto tokens = detail::split_tokens(line);
    if (tokens.empty()) continue;
    if (point >= h.points) {
      throw core::Error(path, "line " + std::to_string(line_no) +
                                  " holds more points than POINTS " + std::to_string(h.points));
    }
    if (tokens.size() != per_point) {
      throw core::Error(path, "line " + std::to_string(line_no) + " (point " +
                                  std::to_string(point) + ") has " + std::to_string(tokens.size()) +
                                  " values, expected " + std::to_string(per_point) +
                                  " (FIELDS with their COUNT)");
    }
    std::uint8_t* record = raw.storage.data() + point * h.point_step;
    std::size_t t = 0;
    for (const auto& f : h.fields) {
      for (std::size_t c = 0; c < f.count; ++c, ++t) {
        if (!detail::parse_ascii_value(tokens[t], f.kind, f.size, record + f.offset + c * f.size)) {
          throw core::Error(
              path, "line " + std::to_string(line_no) + " (point " + std::to_string(point) +
                        "), field " + f.name + ": " + quote(tokens[t]) + " is not a " +
                        (f.kind == Kind::kFloat ? "number" : "whole number in range of its TYPE"));
        }
      }
    }
    ++point;
  }
  if (point != h.points) {
    throw core::Error(path, "DATA ascii holds " + std::to_string(point) +
                                " points, expected POINTS " + std::to_string(h.points));
  }
}

RawCloud read_raw_pcd(const std::string& bytes, const std::string& path) {
  const PcdHeader h = parse_header(bytes, path);
  RawCloud raw;
  raw.fields = h.fields;
  raw.point_step = h.point_step;
  raw.points = static_cast<std::size_t>(h.points);
  switch (h.data) {
    case DataFormat::kAscii:
      decode_ascii(bytes, h, raw, path);
      break;
    case DataFormat::kBinary:
      decode_binary(bytes, h, raw, path);
      break;
    case DataFormat::kBinaryCompressed:
      decode_compressed(bytes, h, raw, path);
      break;
  }
  return raw;
}

std::uint8_t pcl_datatype(const RawField& f) {
  switch (f.kind) {
    case Kind::kInt:
      return f.size == 1   ? pcl::PCLPointField::INT8
             : f.size == 2 ? pcl::PCLPointField::INT16
             : f.size == 4 ? pcl::PCLPointField::INT32
                           : pcl::PCLPointField::INT64;
    case Kind::kUint:
      return f.size == 1   ? pcl::PCLPointField::UINT8
             : f.size == 2 ? pcl::PCLPointField::UINT16
             : f.size == 4 ? pcl::PCLPointField::UINT32
                           : pcl::PCLPointField::UINT64;
    case Kind::kFloat:
      break;
  }
  return f.size == 4 ? pcl::PCLPointField::FLOAT32 : pcl::PCLPointField::FLOAT64;
}

}  // namespace

LoadedCloud load_pcd(const std::string& path) {
  const std::string bytes = detail::read_whole_file(path, "point cloud");
  return detail::to_loaded_cloud(read_raw_pcd(bytes, path), path, "PCD");
}

pcl::PCLPointCloud2 load_pcd_blob(const std::string& path) {
  const std::string bytes = detail::read_whole_file(path, "point cloud");
  const RawCloud raw = read_raw_pcd(bytes, path);
  pcl::PCLPointCloud2 blob;
  for (const RawField& f : raw.fields) {
    pcl::PCLPointField field;
    field.name = f.name;
    field.offset = static_cast<std::uint32_t>(f.offset);
    field.datatype = pcl_datatype(f);
    field.count = static_cast<std::uint32_t>(f.count);
    blob.fields.push_back(std::move(field));
  }
  blob.height = 1;
  blob.width = static_cast<std::uint32_t>(raw.points);
  blob.point_step = static_cast<std::uint32_t>(raw.point_step);
  blob.row_step = blob.point_step * blob.width;
  blob.is_dense = false;
  const std::size_t size = raw.points * raw.point_step;
  if (size > 0) blob.data.assign(raw.data, raw.data + size);
  return blob;
}

void save_pcd(const std::string& path, const Cloud& cloud, PcdFormat format) {
  if (cloud.empty()) {
    // PCL refuses to write empty clouds; an empty cloud is still a valid PCD.
    pcl::PCLPointCloud2 msg;
    Cloud one;
    one.push_back(PointXYZIRT{});
    pcl::toPCLPointCloud2(one, msg);
    msg.width = 0;
    msg.data.clear();
    pcl::PCDWriter writer;
    if (writer.writeASCII(path, msg) < 0) throw core::Error(path, "cannot write PCD");
    return;
  }
  pcl::PCDWriter writer;
  int rc = -1;
  try {
    switch (format) {
      case PcdFormat::kAscii: rc = writer.writeASCII(path, cloud, 9); break;
      case PcdFormat::kBinary: rc = writer.writeBinary(path, cloud); break;
      case PcdFormat::kBinaryCompressed: rc = writer.writeBinaryCompressed(path, cloud); break;
    }
  } catch (const std::exception& e) {
    throw core::Error(path, std::string("cannot write PCD: ") + e.what());
  }
  if (rc < 0) throw core::Error(path, "cannot write PCD (is the folder there and writable?)");
}

}  // namespace rgbdt::cloud
