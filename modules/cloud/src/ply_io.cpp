// PLY reading, by hand: the header is small, and parsing it here lets every count be
// checked against the file's size before anything is allocated for it.
#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <vector>

#include "raw_cloud.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/parse.hpp"

namespace rgbdt::cloud {
namespace {

using detail::Kind;
using detail::quote;
using detail::RawCloud;
using detail::RawField;

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<RawField> properties;  // scalar properties, packed offsets
  std::size_t step = 0;              // bytes per binary record when there are no lists
  bool has_list = false;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  std::size_t data_offset = 0;
};

bool scalar_type(std::string_view name, Kind* kind, std::size_t* size) {
  struct Type {
    const char* name;
    Kind kind;
    std::size_t size;
  };
  static const Type kTypes[] = {
      {"char", Kind::kInt, 1},     {"int8", Kind::kInt, 1},      {"uchar", Kind::kUint, 1},
      {"uint8", Kind::kUint, 1},   {"short", Kind::kInt, 2},     {"int16", Kind::kInt, 2},
      {"ushort", Kind::kUint, 2},  {"uint16", Kind::kUint, 2},   {"int", Kind::kInt, 4},
      {"int32", Kind::kInt, 4},    {"uint", Kind::kUint, 4},     {"uint32", Kind::kUint, 4},
      {"float", Kind::kFloat, 4},  {"float32", Kind::kFloat, 4}, {"double", Kind::kFloat, 8},
      {"float64", Kind::kFloat, 8}};
  for (const auto& t : kTypes) {
    if (name == t.name) {
      *kind = t.kind;
      *size = t.size;
      return true;
    }
  }
  return false;
}

const char* kTypeList = "char uchar short ushort int uint float double (or int8 ... float64)";

PlyHeader parse_header(const std::string& bytes, const std::string& path) {
  if (bytes.empty()) {
    throw core::Error(path, "file is empty (0 bytes), expected a PLY header starting with 'ply'");
  }
  PlyHeader h;
  bool have_format = false;
  detail::HeaderLines lines(bytes, path, "PLY", "'end_header'");
  while (true) {
    const std::string_view line = lines.next();
    const int line_no = lines.line_no();
    const auto where = " (line " + std::to_string(line_no) + ")";
    if (line_no == 1) {
      if (line != "ply") {
        throw core::Error(path, "starts with " + quote(line) + ", expected 'ply' (a PLY file)");
      }
      continue;
    }
    const auto tokens = detail::split_tokens(line);
    if (tokens.empty()) continue;
    const auto key = tokens[0];
    if (key == "comment" || key == "obj_info") continue;
    if (key == "end_header") break;
    if (key == "format") {
      if (have_format || tokens.size() != 3 || tokens[2] != "1.0") {
        throw core::Error(path, "PLY format line " + quote(line) + where +
                                    ", expected one 'format <ascii|binary_little_endian|"
                                    "binary_big_endian> 1.0'");
      }
      if (tokens[1] == "ascii") {
        h.format = PlyFormat::kAscii;
      } else if (tokens[1] == "binary_little_endian") {
        h.format = PlyFormat::kBinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        h.format = PlyFormat::kBinaryBigEndian;
      } else {
        throw core::Error(path, "PLY format " + quote(tokens[1]) + where +
                                    ", expected ascii, binary_little_endian or binary_big_endian");
      }
      have_format = true;
    } else if (key == "element") {
      const auto count =
          tokens.size() == 3 ? core::parse_integer(tokens[2], 0, 0xffffffffLL) : std::nullopt;
      if (!count) {
        throw core::Error(path, "PLY element line " + quote(line) + where +
                                    ", expected 'element <name> <count 0..4294967295>'");
      }
      if (h.elements.size() >= detail::kMaxFields) {
        throw core::Error(path, "PLY header declares more than " +
                                    std::to_string(detail::kMaxFields) + " elements");
      }
      PlyElement e;
      e.name = std::string(tokens[1]);
      e.count = static_cast<std::uint64_t>(*count);
      h.elements.push_back(std::move(e));
    } else if (key == "property") {
      if (h.elements.empty()) {
        throw core::Error(path, "PLY property before any element" + where);
      }
      auto& e = h.elements.back();
      if (tokens.size() == 5 && tokens[1] == "list") {
        Kind kind;
        std::size_t size;
        if (!scalar_type(tokens[2], &kind, &size) || kind == Kind::kFloat ||
            !scalar_type(tokens[3], &kind, &size)) {
          throw core::Error(path, "PLY list property " + quote(line) + where +
                                      ", expected 'property list <integer type> <type> <name>'");
        }
        e.has_list = true;
        continue;
      }
      RawField f;
      if (tokens.size() != 3 || !scalar_type(tokens[1], &f.kind, &f.size)) {
        throw core::Error(path, "PLY property " + quote(line) + where +
                                    ", expected 'property <type> <name>' with type one of " +
                                    kTypeList);
      }
      f.name = std::string(tokens[2]);
      for (const auto& other : e.properties) {
        if (other.name == f.name) {
          throw core::Error(path, "PLY element " + e.name + " repeats property " + f.name + where);
        }
      }
      if (e.properties.size() >= detail::kMaxFields) {
        throw core::Error(path, "PLY element " + e.name + " has more than " +
                                    std::to_string(detail::kMaxFields) + " properties");
      }
      f.offset = e.step;
      e.step += f.size;
      e.properties.push_back(std::move(f));
    } else {
      throw core::Error(path, "PLY header line " + std::to_string(line_no) + " starts with " +
                                  quote(key) +
                                  ", expected format, element, property, comment or end_header");
    }
  }
  if (!have_format) throw core::Error(path, "PLY header has no 'format' line");
  h.data_offset = lines.end();
  return h;
}

bool host_is_little_endian() {
  const std::uint16_t one = 1;
  std::uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Skips `e`'s records in an ASCII body: one non-empty line each.
std::size_t skip_ascii_lines(const std::string& bytes, std::size_t pos, std::uint64_t lines) {
  for (std::uint64_t k = 0; k < lines && pos < bytes.size();) {
    std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos) eol = bytes.size();
    std::string_view line(bytes.data() + pos, eol - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!detail::split_tokens(line).empty()) ++k;
    pos = eol + 1;
  }
  return std::min(pos, bytes.size());
}

}  // namespace

LoadedCloud load_ply(const std::string& path) {
  const std::string bytes = detail::read_whole_file(path, "point cloud");
  const PlyHeader h = parse_header(bytes, path);
  const bool binary = h.format != PlyFormat::kAscii;

  // Where the vertex records start: after the elements declared before them.
  std::size_t pos = h.data_offset;
  const PlyElement* vertex = nullptr;
  for (const auto& e : h.elements) {
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    const std::uint64_t left = bytes.size() - pos;
    if (binary) {
      if (e.has_list) {
        throw core::Error(path, "PLY element " + e.name +
                                    " has list properties and comes before 'vertex', expected "
                                    "vertex first");
      }
      if (e.count * e.step > left) {
        throw core::Error(path, "PLY element " + e.name + " needs " +
                                    std::to_string(e.count * e.step) + " bytes, the file holds " +
                                    std::to_string(left));
      }
      pos += static_cast<std::size_t>(e.count * e.step);
    } else {
      if (e.count * 2 > left + 1) {
        throw core::Error(path, "PLY element " + e.name + " has " + std::to_string(e.count) +
                                    " lines, the file holds only " + std::to_string(left) +
                                    " bytes");
      }
      pos = skip_ascii_lines(bytes, pos, e.count);
    }
  }
  if (!vertex)
    throw core::Error(path, "PLY header has no 'element vertex', expected the points there");
  if (vertex->has_list) {
    throw core::Error(path,
                      "PLY element vertex has a list property, expected scalar properties only");
  }

  RawCloud raw;
  raw.fields = vertex->properties;
  raw.point_step = vertex->step;
  raw.points = static_cast<std::size_t>(vertex->count);
  const std::uint64_t left = bytes.size() - pos;
  if (raw.points > 0 && raw.point_step == 0) {
    throw core::Error(path, "PLY element vertex has no properties, expected x y z");
  }
  if (binary) {
    const std::uint64_t need = vertex->count * vertex->step;
    if (need > left) {
      throw core::Error(path, "PLY element vertex " + std::to_string(vertex->count) + " needs " +
                                  std::to_string(vertex->count) + " vertices x " +
                                  std::to_string(vertex->step) +
                                  " bytes = " + std::to_string(need) + " bytes, the file holds " +
                                  std::to_string(left) + " (truncated, or the count is too large)");
    }
    const bool swap = (h.format == PlyFormat::kBinaryLittleEndian) != host_is_little_endian();
    if (!swap) {
      raw.data = reinterpret_cast<const std::uint8_t*>(bytes.data() + pos);
    } else {
      raw.storage.assign(bytes.begin() + static_cast<std::ptrdiff_t>(pos),
                         bytes.begin() + static_cast<std::ptrdiff_t>(pos + need));
      for (std::size_t i = 0; i < raw.points; ++i) {
        for (const auto& f : raw.fields) {
          auto* p = raw.storage.data() + i * raw.point_step + f.offset;
          std::reverse(p, p + f.size);
        }
      }
      raw.data = raw.storage.data();
    }
    return detail::to_loaded_cloud(raw, path, "PLY");
  }

  const std::size_t per_point = raw.fields.size();
  if (vertex->count * per_point * 2 > left + 1) {
    throw core::Error(path, "PLY element vertex " + std::to_string(vertex->count) + " with " +
                                std::to_string(per_point) + " values each needs at least " +
                                std::to_string(vertex->count * per_point * 2) +
                                " bytes, the file holds " + std::to_string(left));
  }
  raw.storage.assign(raw.points * raw.point_step, 0);
  raw.data = raw.storage.data();
  std::size_t line_no = 1;
  for (std::size_t i = 0; i < pos; ++i) line_no += bytes[i] == '\n';
  std::size_t point = 0;
  for (; point < raw.points && pos < bytes.size(); ++line_no) {
    std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string::npos) eol = bytes.size();
    std::string_view line(bytes.data() + pos, eol - pos);
    pos = eol + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const auto tokens = detail::split_tokens(line);
    if (tokens.empty()) continue;
    if (tokens.size() != per_point) {
      throw core::Error(path, "line " + std::to_string(line_no) + " (vertex " +
                                  std::to_string(point) + ") has " + std::to_string(tokens.size()) +
                                  " values, expected " + std::to_string(per_point) +
                                  " (one per vertex property)");
    }
    std::uint8_t* record = raw.storage.data() + point * raw.point_step;
    for (std::size_t k = 0; k < per_point; ++k) {
      const auto& f = raw.fields[k];
      if (!detail::parse_ascii_value(tokens[k], f.kind, f.size, record + f.offset)) {
        throw core::Error(
            path, "line " + std::to_string(line_no) + " (vertex " + std::to_string(point) +
                      "), property " + f.name + ": " + quote(tokens[k]) + " is not a " +
                      (f.kind == Kind::kFloat ? "number" : "whole number in range of its type"));
      }
    }
    ++point;
  }
  if (point != raw.points) {
    throw core::Error(path, "PLY holds " + std::to_string(point) + " vertices, expected " +
                                std::to_string(raw.points) + " (element vertex)");
  }
  return detail::to_loaded_cloud(raw, path, "PLY");
}

LoadedCloud load_cloud(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".pcd") return load_pcd(path);
  if (ext == ".ply") return load_ply(path);
  throw core::Error(path,
                    "point cloud file has extension " + quote(ext) + ", expected .pcd or .ply");
}

}  // namespace rgbdt::cloud
