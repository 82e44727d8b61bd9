#include "rgbdt/thermal_camera/tau2_protocol.hpp"

#include <cstdio>
#include <stdexcept>

namespace rgbdt::thermal_camera::tau2 {
namespace {

std::string hex8(unsigned v) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%02X", v & 0xFFu);
  return b;
}

std::string hex16(unsigned v) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%04X", v & 0xFFFFu);
  return b;
}

uint16_t be16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }

}  // namespace

std::string to_string(Status status) {
  switch (status) {
    case Status::kOk:
      return "CAM_OK";
    case Status::kBusy:
      return "CAM_BUSY";
    case Status::kNotReady:
      return "CAM_NOT_READY";
    case Status::kRangeError:
      return "CAM_RANGE_ERROR";
    case Status::kChecksumError:
      return "CAM_CHECKSUM_ERROR";
    case Status::kUndefinedProcessError:
      return "CAM_UNDEFINED_PROCESS_ERROR";
    case Status::kUndefinedFunctionError:
      return "CAM_UNDEFINED_FUNCTION_ERROR";
    case Status::kTimeoutError:
      return "CAM_TIMEOUT_ERROR";
    case Status::kByteCountError:
      return "CAM_BYTE_COUNT_ERROR";
    case Status::kFeatureNotEnabled:
      return "CAM_FEATURE_NOT_ENABLED";
  }
  return "status " + hex8(static_cast<unsigned>(status));
}

std::string function_name(uint8_t function) {
  switch (static_cast<Function>(function)) {
    case Function::kNoOp:
      return "NO_OP";
    case Function::kSetDefaults:
      return "SET_DEFAULTS";
    case Function::kCameraReset:
      return "CAMERA_RESET";
    case Function::kSerialNumber:
      return "SERIAL_NUMBER";
    case Function::kGetRevision:
      return "GET_REVISION";
    case Function::kGainMode:
      return "GAIN_MODE";
    case Function::kFfcModeSelect:
      return "FFC_MODE_SELECT";
    case Function::kDoFfc:
      return "DO_FFC";
    case Function::kReadSensor:
      return "READ_SENSOR";
    case Function::kShutterTemp:
      return "SHUTTER_TEMP";
    case Function::kTlinCommands:
      return "TLIN_COMMANDS";
  }
  return "function " + hex8(function);
}

uint16_t crc16_ccitt(const uint8_t* data, size_t size, uint16_t crc) {
  for (size_t i = 0; i < size; ++i) {
    crc ^= static_cast<uint16_t>(data[i] << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000u) ? static_cast<uint16_t>((crc << 1) ^ 0x1021u)
                            : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

std::vector<uint8_t> encode(const Packet& packet) {
  if (packet.payload.size() > kMaxPayloadBytes) {
    throw std::invalid_argument("Tau2 packet payload of " + std::to_string(packet.payload.size()) +
                                " bytes, expected at most " + std::to_string(kMaxPayloadBytes));
  }
  const auto n = static_cast<uint16_t>(packet.payload.size());
  std::vector<uint8_t> out = {kProcessCode,
                              packet.status,
                              packet.reserved,
                              packet.function,
                              static_cast<uint8_t>(n >> 8),
                              static_cast<uint8_t>(n & 0xFF)};
  const uint16_t crc1 = crc16_ccitt(out.data(), 6);
  out.push_back(static_cast<uint8_t>(crc1 >> 8));
  out.push_back(static_cast<uint8_t>(crc1 & 0xFF));
  out.insert(out.end(), packet.payload.begin(), packet.payload.end());
  const uint16_t crc2 = crc16_ccitt(out.data(), out.size());
  out.push_back(static_cast<uint8_t>(crc2 >> 8));
  out.push_back(static_cast<uint8_t>(crc2 & 0xFF));
  return out;
}

ParseResult parse(const uint8_t* data, size_t size) {
  ParseResult r;
  if (size == 0) return r;
  if (data[0] != kProcessCode) {
    r.kind = ParseResult::Kind::kError;
    r.error = "process code " + hex8(data[0]) + ", expected " + hex8(kProcessCode);
    return r;
  }
  if (size < kHeaderBytes) return r;
  const uint16_t crc1 = be16(data + 6);
  const uint16_t crc1_computed = crc16_ccitt(data, 6);
  if (crc1 != crc1_computed) {
    r.kind = ParseResult::Kind::kError;
    r.error = "header CRC " + hex16(crc1) + " does not match the computed " + hex16(crc1_computed);
    return r;
  }
  const size_t count = be16(data + 4);
  if (count > kMaxPayloadBytes) {
    r.kind = ParseResult::Kind::kError;
    r.error = "byte count " + std::to_string(count) + " exceeds the maximum of " +
              std::to_string(kMaxPayloadBytes);
    return r;
  }
  const size_t total = kHeaderBytes + count + 2;
  if (size < total) {
    r.needed = total;
    return r;
  }
  const uint16_t crc2 = be16(data + kHeaderBytes + count);
  const uint16_t crc2_computed = crc16_ccitt(data, kHeaderBytes + count);
  if (crc2 != crc2_computed) {
    r.kind = ParseResult::Kind::kError;
    r.error = "payload CRC " + hex16(crc2) + " does not match the computed " +
              hex16(crc2_computed) + " (byte count " + std::to_string(count) + ")";
    return r;
  }
  r.kind = ParseResult::Kind::kPacket;
  r.consumed = total;
  r.packet.status = data[1];
  r.packet.reserved = data[2];
  r.packet.function = data[3];
  r.packet.payload.assign(data + kHeaderBytes, data + kHeaderBytes + count);
  return r;
}

Packet decode(const uint8_t* data, size_t size, const std::string& source) {
  const ParseResult r = parse(data, size);
  switch (r.kind) {
    case ParseResult::Kind::kError:
      throw ProtocolError(source, r.error);
    case ParseResult::Kind::kNeedMore:
      throw ProtocolError(source,
                          "truncated packet: " + std::to_string(size) + " bytes, expected " +
                              std::to_string(r.needed) +
                              (size >= kHeaderBytes ? " from its byte count" : " at least"));
    case ParseResult::Kind::kPacket:
      break;
  }
  if (r.consumed != size) {
    throw ProtocolError(source, std::to_string(size - r.consumed) +
                                    " trailing bytes after a packet of " +
                                    std::to_string(r.consumed) + " bytes (wrong byte count?)");
  }
  return r.packet;
}

std::vector<uint8_t> words(std::initializer_list<uint16_t> values) {
  std::vector<uint8_t> out;
  for (uint16_t v : values) {
    out.push_back(static_cast<uint8_t>(v >> 8));
    out.push_back(static_cast<uint8_t>(v & 0xFF));
  }
  return out;
}

uint16_t word_at(const std::vector<uint8_t>& payload, size_t index, const std::string& what) {
  if (payload.size() < 2 * (index + 1)) {
    throw ProtocolError(what, "reply payload of " + std::to_string(payload.size()) +
                                  " bytes, expected at least " + std::to_string(2 * (index + 1)));
  }
  return be16(payload.data() + 2 * index);
}

}  // namespace rgbdt::thermal_camera::tau2
