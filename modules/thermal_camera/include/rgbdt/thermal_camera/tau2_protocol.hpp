#pragma once
/// \file
/// The FLIR Tau2 serial command protocol (FLIR "Tau 2 / Quark 2 Software Interface
/// Description Document", 102-PS242-43, section "Serial Communication Technical Details").
///
/// Every message, from the host and from the camera, is one packet:
///
///   byte 0      process code, always 0x6E
///   byte 1      status (0x00 from the host; the camera's reply status, see Status)
///   byte 2      reserved (0x00)
///   byte 3      function code (see Function)
///   bytes 4-5   byte count N of the payload, most significant byte first
///   bytes 6-7   CRC1: CRC-16-CCITT of bytes 0-5
///   bytes 8..   N payload bytes (arguments / reply data, 16-bit words big-endian)
///   last 2      CRC2: CRC-16-CCITT of every byte before it (bytes 0 .. 7+N)
///
/// The CRC is CCITT polynomial 0x1021, initial value 0x0000, no reflection (also known as
/// CRC-16/XMODEM). Example from the IDD's arithmetic: FFC_MODE_SELECT "get" is
/// 6E 00 00 0B 00 00 2F 4A 00 00 (CRC2 of a packet without payload is always 0).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/core/error.hpp"

namespace rgbdt::thermal_camera::tau2 {

constexpr uint8_t kProcessCode = 0x6E;
constexpr size_t kHeaderBytes = 8;  ///< bytes 0-7, CRC1 included
constexpr size_t kMinPacketBytes = kHeaderBytes + 2;
/// Largest payload accepted. The IDD's longest transfers (READ_MEMORY) carry 256 bytes;
/// anything much longer is a corrupt byte count, not a packet worth waiting for.
constexpr size_t kMaxPayloadBytes = 512;

/// Function codes used here (IDD table "Tau 2 Serial Commands").
enum class Function : uint8_t {
  kNoOp = 0x00,           ///< no operation; the camera echoes it (link check)
  kSetDefaults = 0x01,    ///< save current settings as power-on defaults
  kCameraReset = 0x02,    ///< reboot the core
  kSerialNumber = 0x04,   ///< reply: camera serial (4 bytes), sensor serial (4 bytes)
  kGetRevision = 0x05,    ///< reply: software major/minor, firmware major/minor (2 bytes each)
  kGainMode = 0x0A,       ///< get (no args) / set (1 word): 0 auto, 1 low, 2 high, 3 manual
  kFfcModeSelect = 0x0B,  ///< get / set: 0 manual, 1 automatic, 2 external
  kDoFfc = 0x0C,          ///< run a flat-field correction now
  kReadSensor = 0x20,     ///< arg 0x0000: FPA temperature, reply signed word [degC x 10]
  kShutterTemp = 0x4D,    ///< get: shutter temperature, reply signed word [degC x 100]
  kTlinCommands = 0x8E,   ///< TLinear sub-commands, see TlinSubcommand
};

/// TLIN_COMMANDS (0x8E) first argument word. Get: 2-byte payload (sub-command), reply one
/// word; set: 4-byte payload (sub-command, value). Radiometric Tau2 cores only.
enum class TlinSubcommand : uint16_t {
  kResolution = 0x0010,    ///< value 0: low resolution (0.4 K/count), 1: high (0.04 K/count)
  kOutputEnable = 0x0040,  ///< value 0: raw counts, 1: TLinear temperatures
};

/// Reply status byte (IDD "Status Byte Definitions").
enum class Status : uint8_t {
  kOk = 0x00,
  kBusy = 0x01,
  kNotReady = 0x02,
  kRangeError = 0x03,
  kChecksumError = 0x04,
  kUndefinedProcessError = 0x05,
  kUndefinedFunctionError = 0x06,
  kTimeoutError = 0x07,
  kByteCountError = 0x09,
  kFeatureNotEnabled = 0x0A,
};
/// "CAM_OK", "CAM_RANGE_ERROR", ...; "status 0xNN" for values outside the table.
std::string to_string(Status status);
/// Name of a function code ("DO_FFC"), or "function 0xNN".
std::string function_name(uint8_t function);

/// CRC-16-CCITT (polynomial 0x1021, MSB first) continuing from `crc` (0 to start).
uint16_t crc16_ccitt(const uint8_t* data, size_t size, uint16_t crc = 0);

struct Packet {
  uint8_t status = 0;    ///< Status for replies; 0 for commands
  uint8_t function = 0;  ///< Function code
  std::vector<uint8_t> payload;
  /// Byte 2. Sent as 0; kept as received because it is covered by the header CRC, so that
  /// encode(parse(bytes)) reproduces the bytes exactly (found by fuzzing).
  uint8_t reserved = 0;
};

/// The bytes of a packet with both CRCs. Throws std::invalid_argument when the payload
/// is longer than kMaxPayloadBytes.
std::vector<uint8_t> encode(const Packet& packet);

/// A malformed packet: the message says which field, what was received and what was
/// expected (e.g. "header CRC 0x1234 does not match the computed 0x2F4A").
class ProtocolError : public core::Error {
 public:
  using core::Error::Error;
};

/// Result of looking for one packet at the start of a byte stream.
struct ParseResult {
  enum class Kind {
    kPacket,    ///< `packet` holds a valid packet of `consumed` bytes
    kNeedMore,  ///< the bytes are a valid prefix; `needed` bytes in total are required
    kError,     ///< the bytes cannot start a valid packet; `error` says why
  };
  Kind kind = Kind::kNeedMore;
  Packet packet;
  size_t consumed = 0;              ///< bytes of the packet (kPacket)
  size_t needed = kMinPacketBytes;  ///< total bytes required (kNeedMore)
  std::string error;
};

/// Incremental parser: checks the process code, the header CRC as soon as 8 bytes are
/// there, the byte count against kMaxPayloadBytes, then the payload CRC. Never reads
/// past `size`.
ParseResult parse(const uint8_t* data, size_t size);

/// Strict parser for exactly one packet: throws ProtocolError (naming `source`) for a
/// bad field, a truncated packet or trailing bytes.
Packet decode(const uint8_t* data, size_t size, const std::string& source = "Tau2 packet");

/// Big-endian 16-bit words, the IDD's argument encoding.
std::vector<uint8_t> words(std::initializer_list<uint16_t> values);
/// Word `index` of a payload; throws ProtocolError if the payload is too short.
uint16_t word_at(const std::vector<uint8_t>& payload, size_t index, const std::string& what);

}  // namespace rgbdt::thermal_camera::tau2
