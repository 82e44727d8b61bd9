#include "raw_cloud.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/parse.hpp"

namespace rgbdt::cloud::detail {
namespace {

double read_value(const std::uint8_t* p, const RawField& f) {
  switch (f.kind) {
    case Kind::kFloat:
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
      {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    case Kind::kInt:
      switch (f.size) {
        case 1: {
          std::int8_t v;
          std::memcpy(&v, p, 1);
          return v;
        }
        case 2: {
          std::int16_t v;
          std::memcpy(&v, p, 2);
          return v;
        }
        case 4: {
          std::int32_t v;
          std::memcpy(&v, p, 4);
          return v;
        }
        default: {
          std::int64_t v;
          std::memcpy(&v, p, 8);
          return static_cast<double>(v);
        }
      }
    case Kind::kUint:
      switch (f.size) {
        case 1: {
          std::uint8_t v;
          std::memcpy(&v, p, 1);
          return v;
        }
        case 2: {
          std::uint16_t v;
          std::memcpy(&v, p, 2);
          return v;
        }
        case 4: {
          std::uint32_t v;
          std::memcpy(&v, p, 4);
          return v;
        }
        default: {
          std::uint64_t v;
          std::memcpy(&v, p, 8);
          return static_cast<double>(v);
        }
      }
  }
  return std::nan("");
}

const RawField* find_field(const RawCloud& raw, std::initializer_list<const char*> names) {
  for (const char* name : names) {
    for (const auto& f : raw.fields) {
      if (normalized_name(f.name) == name) return &f;
    }
  }
  return nullptr;
}

// double -> float without undefined behaviour: beyond float's range gives +-inf (which the
// value checks then refuse), NaN stays NaN.
float to_float(double v) {
  if (v > std::numeric_limits<float>::max()) return std::numeric_limits<float>::infinity();
  if (v < -std::numeric_limits<float>::max()) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

template <typename T>
void store(double v, std::uint8_t* out) {
  const T t = static_cast<T>(v);
  std::memcpy(out, &t, sizeof(T));
}

bool parse_float_token(std::string_view token, double* out) {
  if (auto v = core::parse_finite_double(token)) {
    *out = *v;
    return true;
  }
  std::string lower(token);
  for (auto& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "nan" || lower == "-nan" || lower == "+nan") {
    *out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (lower == "inf" || lower == "+inf" || lower == "infinity") {
    *out = std::numeric_limits<double>::infinity();
    return true;
  }
  if (lower == "-inf" || lower == "-infinity") {
    *out = -std::numeric_limits<double>::infinity();
    return true;
  }
  // A decimal too large for a double (1e999) is a number, just not a finite one.
  if (!lower.empty() && lower.find_first_not_of("+-0123456789.e") == std::string::npos &&
      lower.find_first_of("0123456789") != std::string::npos) {
    char* end = nullptr;
    const double v = std::strtod(lower.c_str(), &end);
    if (end == lower.c_str() + lower.size() && std::isinf(v)) {
      *out = v;
      return true;
    }
  }
  return false;
}

}  // namespace

std::string_view HeaderLines::next() {
  if (pos_ >= bytes_.size()) {
    throw core::Error(path_, format_ + " header ends after " + std::to_string(line_no_) +
                                 " lines without " + terminator_);
  }
  std::size_t eol = bytes_.find('\n', pos_);
  if (eol == std::string::npos) eol = bytes_.size();
  if (eol > kMaxHeaderBytes) {
    throw core::Error(path_, format_ + " header has no " + terminator_ + " within the first " +
                                 std::to_string(kMaxHeaderBytes) + " bytes (is this a " +
                                 format_ + " file?)");
  }
  std::string_view line(bytes_.data() + pos_, eol - pos_);
  pos_ = eol + 1;
  ++line_no_;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

std::vector<std::string_view> split_tokens(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

std::string read_whole_file(const std::string& path, const char* what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) {
    throw core::Error(path, std::string(what) + " file does not exist");
  }
  if (!fs::is_regular_file(status)) {
    throw core::Error(path, std::string("is not a regular file, expected a ") + what + " file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw core::Error(path, std::string("cannot open ") + what + " file for reading");
  const auto size = fs::file_size(path, ec);
  if (ec) throw core::Error(path, std::string("cannot read the size of ") + what + " file");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    throw core::Error(path, "read " + std::to_string(in.gcount()) + " of " + std::to_string(size) +
                                " bytes (file changed or unreadable)");
  }
  return bytes;
}

std::string quote(std::string_view text) {
  std::string out = "'";
  const std::size_t n = std::min<std::size_t>(text.size(), 40);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f && c != '\'') {
      out += static_cast<char>(c);
    } else {
      static const char* hex = "0123456789abcdef";
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  if (text.size() > n) out += "...";
  return out + "'";
}

std::string show(double value, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << value;
  return s.str();
}

std::string normalized_name(std::string_view name) {
  std::string out(name);
  for (auto& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (out.rfind("scalar_", 0) == 0 && out.size() > 7) out.erase(0, 7);
  return out;
}

bool parse_ascii_value(std::string_view token, Kind kind, std::size_t size, std::uint8_t* out) {
  double v = 0.0;
  if (kind == Kind::kFloat) {
    if (!parse_float_token(token, &v)) return false;
    if (size == 4) {
      const float f = to_float(v);  // beyond float range becomes inf, which the checks catch
      std::memcpy(out, &f, 4);
    } else {
      store<double>(v, out);
    }
    return true;
  }
  // Integers: whole numbers within the type's range ("3" or "3.0"; not "3.5", "0x3").
  const auto parsed = core::parse_finite_double(token);
  if (!parsed || std::floor(*parsed) != *parsed) return false;
  v = *parsed;
  const double bits = 8.0 * static_cast<double>(size);
  const double lo = kind == Kind::kInt ? -std::ldexp(1.0, static_cast<int>(bits) - 1) : 0.0;
  const double hi = kind == Kind::kInt ? std::ldexp(1.0, static_cast<int>(bits) - 1) - 1
                                       : std::ldexp(1.0, static_cast<int>(bits)) - 1;
  if (v < lo || v > hi) return false;
  if (kind == Kind::kInt) {
    switch (size) {
      case 1:
        store<std::int8_t>(v, out);
        break;
      case 2:
        store<std::int16_t>(v, out);
        break;
      case 4:
        store<std::int32_t>(v, out);
        break;
      default:
        store<std::int64_t>(v, out);
        break;
    }
  } else {
    switch (size) {
      case 1:
        store<std::uint8_t>(v, out);
        break;
      case 2:
        store<std::uint16_t>(v, out);
        break;
      case 4:
        store<std::uint32_t>(v, out);
        break;
      default:
        // 2^64 - 1 rounds up to 2^64 as a double; clamp below it before converting.
        store<std::uint64_t>(std::min(v, 18446744073709549568.0), out);
        break;
    }
  }
  return true;
}

LoadedCloud to_loaded_cloud(const RawCloud& raw, const std::string& path, const char* format) {
  const auto* fx = find_field(raw, {"x"});
  const auto* fy = find_field(raw, {"y"});
  const auto* fz = find_field(raw, {"z"});
  if (!fx || !fy || !fz) {
    std::string fields;
    for (const auto& f : raw.fields) fields += (fields.empty() ? "" : " ") + f.name;
    throw core::Error(
        path, std::string(format) + " has fields '" + fields + "', expected at least x y z");
  }
  const auto* fi = find_field(raw, {"intensity", "i", "reflectivity"});
  const auto* fr = find_field(raw, {"ring", "line", "laser_id"});
  const auto* ft = find_field(raw, {"t", "time", "timestamp"});

  LoadedCloud out;
  out.has_intensity = fi != nullptr;
  out.has_ring = fr != nullptr;
  out.has_t = ft != nullptr;
  out.cloud.reset(new Cloud);
  const std::size_t n = raw.points;
  const auto at = [&](std::size_t i, const RawField& f) {
    return read_value(raw.data + i * raw.point_step + f.offset, f);
  };
  const auto finite_xyz = [&](std::size_t i) {
    return std::isfinite(at(i, *fx)) && std::isfinite(at(i, *fy)) && std::isfinite(at(i, *fz));
  };
  // Other tools store absolute times ("time", "timestamp"); ours is relative to the
  // cloud's first point, so subtract the earliest one (in double, before narrowing).
  double t0 = 0.0;
  const bool absolute_time = ft && normalized_name(ft->name) != "t";
  if (absolute_time) {
    t0 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < n; ++i) {
      const double v = at(i, *ft);
      if (std::isfinite(v) && finite_xyz(i)) t0 = std::min(t0, v);
    }
    if (!std::isfinite(t0)) t0 = 0.0;
  }
  const auto fail = [&](std::size_t i, const RawField& f, double v, const std::string& expected) {
    // A float field shows the digits a float holds (1e30, not 1.000000015e+30).
    const int digits = f.kind == Kind::kFloat && f.size == 4 ? 7 : 10;
    throw core::Error(path, "point " + std::to_string(i) + ": " + f.name + " = " + show(v, digits) +
                                ", expected " + expected);
  };
  out.cloud->reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = at(i, *fx), y = at(i, *fy), z = at(i, *fz);
    // A missing return (NaN in organised clouds) is dropped, not an error.
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;
    PointXYZIRT p;
    p.x = to_float(x);
    p.y = to_float(y);
    p.z = to_float(z);
    if (!std::isfinite(p.x)) fail(i, *fx, x, "a coordinate within float range");
    if (!std::isfinite(p.y)) fail(i, *fy, y, "a coordinate within float range");
    if (!std::isfinite(p.z)) fail(i, *fz, z, "a coordinate within float range");
    if (fi) {
      const double v = at(i, *fi);
      p.intensity = to_float(v);
      if (!std::isfinite(p.intensity)) fail(i, *fi, v, "a finite intensity");
    }
    if (fr) {
      const double v = at(i, *fr);
      if (!(v >= 0.0 && v <= kMaxRing) || std::floor(v) != v) {
        fail(i, *fr, v, "a scan-line index, a whole number in 0.." + std::to_string(kMaxRing));
      }
      p.ring = static_cast<std::uint16_t>(v);
    }
    if (ft) {
      const double v = at(i, *ft);
      const double rel = v - t0;
      if (!std::isfinite(v) || !(std::abs(rel) <= kMaxRelativeTime)) {
        fail(i, *ft, absolute_time ? rel : v,
             std::string("a finite time within ") + show(kMaxRelativeTime) +
                 " s of the cloud's first point" +
                 (absolute_time ? " (value shown relative to the earliest, " + show(t0) + " s)"
                                : ""));
      }
      p.t = to_float(rel);
    }
    out.cloud->push_back(p);
  }
  out.cloud->width = static_cast<std::uint32_t>(out.cloud->size());
  out.cloud->height = 1;
  out.cloud->is_dense = true;
  return out;
}

}  // namespace rgbdt::cloud::detail
