#include "rgbdt/tilt_lidar/scip.hpp"

#include <stdexcept>

namespace rgbdt::tilt_lidar::scip {

namespace {

constexpr std::size_t kMaxFrame = 1 << 16;  // a UTM-30LX ME scan is ~6.7 kB

bool parse_digits(std::string_view s, int& out) {
  out = 0;
  for (const char c : s) {
    if (c < '0' || c > '9') return false;
    out = out * 10 + (c - '0');
  }
  return true;
}

bool line_checksum_ok(const std::string& line) {
  if (line.empty()) return false;
  const std::string_view payload(line.data(), line.size() - 1);
  const char sum = line.back();
  if (checksum(payload) == sum) return true;
  // Info lines (VV/PP/II) "KEY:value;S": the sum covers the text before ';'.
  return !payload.empty() && payload.back() == ';' && checksum(payload.substr(0, payload.size() - 1)) == sum;
}

}  // namespace

char checksum(std::string_view payload) {
  unsigned sum = 0;
  for (const char c : payload) sum += static_cast<unsigned char>(c);
  return static_cast<char>((sum & 0x3F) + 0x30);
}

std::string encode(std::uint32_t value, int chars) {
  if (chars < 1 || chars > 4 || (chars < 4 && value >= (1u << (6 * chars))) || value >= (1u << 24)) {
    throw std::invalid_argument("scip::encode: value " + std::to_string(value) + " does not fit in " +
                                std::to_string(chars) + " characters");
  }
  std::string out(static_cast<std::size_t>(chars), '0');
  for (int k = chars - 1; k >= 0; --k) {
    out[static_cast<std::size_t>(k)] = static_cast<char>((value & 0x3F) + 0x30);
    value >>= 6;
  }
  return out;
}

std::optional<std::uint32_t> decode(std::string_view field) {
  if (field.empty() || field.size() > 4) return std::nullopt;
  std::uint32_t v = 0;
  for (const char c : field) {
    const int d = static_cast<unsigned char>(c) - 0x30;
    if (d < 0 || d > 0x3F) return std::nullopt;
    v = (v << 6) | static_cast<std::uint32_t>(d);
  }
  return v;
}

std::string encode_response(const Response& r) {
  std::string out = r.echo + "\n" + r.status + checksum(r.status) + "\n";
  for (const auto& line : r.lines) {
    const bool info = !line.empty() && line.back() == ';';
    out += line;
    out += checksum(info ? std::string_view(line).substr(0, line.size() - 1) : std::string_view(line));
    out += '\n';
  }
  out += '\n';
  return out;
}

void ResponseParser::feed(std::string_view bytes) { buffer_.append(bytes.data(), bytes.size()); }

std::vector<std::string> ResponseParser::take_errors() {
  std::vector<std::string> out;
  out.swap(errors_);
  return out;
}

std::optional<Response> ResponseParser::next() {
  for (;;) {
    const std::size_t end = buffer_.find("\n\n");
    if (end == std::string::npos) {
      if (buffer_.size() > kMaxFrame) {
        errors_.push_back("no frame end within " + std::to_string(kMaxFrame) + " bytes; " +
                          std::to_string(buffer_.size()) + " bytes discarded");
        buffer_.clear();
      }
      return std::nullopt;
    }
    const std::string frame = buffer_.substr(0, end + 1);
    buffer_.erase(0, end + 2);
    std::vector<std::string> lines;
    std::size_t pos = 0;
    bool too_long = false;
    while (pos < frame.size()) {
      const std::size_t lf = frame.find('\n', pos);
      if (lf - pos > kMaxLine) too_long = true;
      lines.emplace_back(frame.substr(pos, lf - pos));
      pos = lf + 1;
    }
    if (too_long) {
      errors_.push_back("line longer than " + std::to_string(kMaxLine) + " bytes; frame skipped");
      continue;
    }
    if (lines.size() < 2) {
      errors_.push_back("frame without echo and status line skipped");
      continue;
    }
    Response r;
    r.echo = lines[0];
    const std::string& status = lines[1];
    if (status.size() != 3 || checksum(std::string_view(status).substr(0, 2)) != status[2]) {
      errors_.push_back("bad status line '" + status.substr(0, 16) + "' after '" + r.echo.substr(0, 32) + "'");
      continue;
    }
    r.status = status.substr(0, 2);
    bool ok = true;
    for (std::size_t k = 2; k < lines.size(); ++k) {
      if (!line_checksum_ok(lines[k])) {
        errors_.push_back("checksum mismatch in data line " + std::to_string(k - 2) + " of '" +
                          r.echo.substr(0, 32) + "'");
        ok = false;
        break;
      }
      r.lines.push_back(lines[k].substr(0, lines[k].size() - 1));
    }
    if (ok) return r;
  }
}

std::vector<std::string> encode_scan_lines(const ScanFrame& frame) {
  if (!frame.intensity.empty() && frame.intensity.size() != frame.ranges_mm.size()) {
    throw std::invalid_argument("scip::encode_scan_lines: intensity size differs from ranges");
  }
  std::vector<std::string> lines{encode(frame.timestamp_ms & 0xFFFFFF, 4)};
  std::string data;
  data.reserve(frame.ranges_mm.size() * 6);
  for (std::size_t i = 0; i < frame.ranges_mm.size(); ++i) {
    data += encode(std::min<std::uint32_t>(frame.ranges_mm[i], 0x3FFFF), 3);
    if (!frame.intensity.empty()) data += encode(std::min<std::uint32_t>(frame.intensity[i], 0x3FFFF), 3);
  }
  for (std::size_t p = 0; p < data.size(); p += 64) lines.push_back(data.substr(p, 64));
  return lines;
}

std::optional<ScanFrame> decode_scan_lines(const std::vector<std::string>& lines, int beams, bool intensity,
                                           std::string* why) {
  auto fail = [why](const std::string& m) -> std::optional<ScanFrame> {
    if (why) *why = m;
    return std::nullopt;
  };
  if (beams < 0) return fail("negative beam count");
  if (lines.empty() || lines[0].size() != 4) return fail("missing 4-character timestamp line");
  ScanFrame f;
  const auto ts = decode(lines[0]);
  if (!ts) return fail("bad timestamp characters");
  f.timestamp_ms = *ts;
  std::string data;
  for (std::size_t k = 1; k < lines.size(); ++k) data += lines[k];
  const std::size_t per_beam = intensity ? 6 : 3;
  if (data.size() != static_cast<std::size_t>(beams) * per_beam) {
    return fail("scan payload has " + std::to_string(data.size()) + " characters, expected " +
                std::to_string(static_cast<std::size_t>(beams) * per_beam));
  }
  f.ranges_mm.resize(static_cast<std::size_t>(beams));
  if (intensity) f.intensity.resize(static_cast<std::size_t>(beams));
  for (std::size_t i = 0; i < static_cast<std::size_t>(beams); ++i) {
    const auto r = decode(std::string_view(data).substr(i * per_beam, 3));
    if (!r) return fail("bad range characters at beam " + std::to_string(i));
    f.ranges_mm[i] = *r;
    if (intensity) {
      const auto v = decode(std::string_view(data).substr(i * per_beam + 3, 3));
      if (!v) return fail("bad intensity characters at beam " + std::to_string(i));
      f.intensity[i] = *v;
    }
  }
  return f;
}

std::optional<MeasurementCommand> parse_measurement_command(std::string_view line) {
  if (line.size() != 15 || line[0] != 'M' || (line[1] != 'D' && line[1] != 'E')) return std::nullopt;
  MeasurementCommand c;
  c.intensity = line[1] == 'E';
  if (!parse_digits(line.substr(2, 4), c.start_step) || !parse_digits(line.substr(6, 4), c.end_step) ||
      !parse_digits(line.substr(10, 2), c.cluster) || !parse_digits(line.substr(12, 1), c.interval) ||
      !parse_digits(line.substr(13, 2), c.scans)) {
    return std::nullopt;
  }
  if (c.cluster == 0) c.cluster = 1;  // "00" means no grouping, as "01"
  if (c.end_step < c.start_step) return std::nullopt;
  return c;
}

}  // namespace rgbdt::tilt_lidar::scip
