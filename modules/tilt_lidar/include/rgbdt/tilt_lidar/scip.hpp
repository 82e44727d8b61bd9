#pragma once
/// \file
/// SCIP 2.0, the protocol of Hokuyo URG/UTM scanners, kept apart from any transport so
/// that tests and fuzzers feed bytes.
///
/// A command is one ASCII line ending in LF ("BM\n", "MD0000108001000\n"). The device
/// answers with the echo of the command line, a status line (2 chars + checksum), data
/// lines (payload + checksum char) and an empty line:
///
///   MD0000108001000\n  99b\n  <4-char timestamp><sum>\n  <64 chars><sum>\n ... \n
///
/// The checksum of a line is the sum of its payload bytes, lower 6 bits, plus 0x30.
/// Numbers are sent in 2/3/4-char encodings: 6 bits per char, each plus 0x30.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rgbdt::tilt_lidar::scip {

/// Checksum character of a line payload.
char checksum(std::string_view payload);

/// Encodes value in `chars` characters (2, 3 or 4); throws std::invalid_argument if the
/// value does not fit (>= 2^(6 chars)).
std::string encode(std::uint32_t value, int chars);
/// Decodes a 1..4 character field; nullopt if a character is outside 0x30..0x6F.
std::optional<std::uint32_t> decode(std::string_view field);

/// One complete device response.
struct Response {
  std::string echo;                ///< command line without LF
  std::string status;              ///< two characters ("00", "99", ...)
  std::vector<std::string> lines;  ///< data lines without checksum and LF
};

/// Serialises a response, adding checksums. For VV/PP/II lines ("MODL:...;") the
/// checksum covers the text before the ';', as the protocol says; otherwise the line.
std::string encode_response(const Response& response);

/// Incremental response parser. Feed bytes as they arrive; complete responses are
/// returned by next(). A line with a wrong checksum or a malformed frame is reported via
/// error() and skipped up to the next empty line (resynchronisation), never thrown.
class ResponseParser {
 public:
  void feed(std::string_view bytes);
  /// The next complete response, if any.
  std::optional<Response> next();
  /// Problems found since the last call (bad checksum, overlong line, ...), then cleared.
  std::vector<std::string> take_errors();
  std::size_t buffered() const { return buffer_.size(); }

  static constexpr std::size_t kMaxLine = 4096;  ///< longer lines are rejected

 private:
  std::string buffer_;
  std::vector<std::string> errors_;
};

/// A distance scan (MD/GD: ranges; ME/GE: ranges + intensities).
struct ScanFrame {
  std::uint32_t timestamp_ms = 0;        ///< device clock, 24 bits
  std::vector<std::uint32_t> ranges_mm;  ///< < 20 mm means "no return" on a UTM-30LX
  std::vector<std::uint32_t> intensity;  ///< empty unless ME/GE
};

/// The data lines of a scan response: timestamp line, then the 3-char-encoded values
/// (interleaved range, intensity for ME) split into 64-char lines.
std::vector<std::string> encode_scan_lines(const ScanFrame& frame);
/// Inverse of encode_scan_lines; nullopt with `why` set if the payload is malformed
/// (wrong length for `beams`, bad characters).
std::optional<ScanFrame> decode_scan_lines(const std::vector<std::string>& lines, int beams, bool intensity,
                                           std::string* why = nullptr);

/// A parsed measurement command "MDsssseeeeccinn" / "ME...".
struct MeasurementCommand {
  bool intensity = false;  ///< ME
  int start_step = 0, end_step = 0, cluster = 1, interval = 0, scans = 0;  ///< scans 0 = forever
};
std::optional<MeasurementCommand> parse_measurement_command(std::string_view line);

}  // namespace rgbdt::tilt_lidar::scip
