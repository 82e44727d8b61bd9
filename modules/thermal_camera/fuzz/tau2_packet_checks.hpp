#pragma once
// Properties every input must satisfy, shared by the libFuzzer target and the gtest that
// replays the kept corpus. Returns an empty string when they hold, else what broke.
#include <string>

#include "rgbdt/thermal_camera/tau2.hpp"
#include "rgbdt/thermal_camera/tau2_protocol.hpp"

namespace rgbdt::thermal_camera::fuzz {

inline std::string check_tau2_input(const uint8_t* data, size_t size) {
  namespace t2 = rgbdt::thermal_camera::tau2;
  // 1. The incremental parser stays in bounds and a packet it accepts re-encodes to the
  //    very bytes it came from.
  const t2::ParseResult r = t2::parse(data, size);
  if (r.kind == t2::ParseResult::Kind::kPacket) {
    if (r.consumed > size) return "parse consumed more bytes than given";
    if (r.packet.payload.size() > t2::kMaxPayloadBytes) return "payload above the maximum";
    const auto again = t2::encode(r.packet);
    if (again.size() != r.consumed) return "re-encoded size differs";
    for (size_t i = 0; i < again.size(); ++i) {
      if (again[i] != data[i]) return "re-encoded bytes differ at " + std::to_string(i);
    }
  } else if (r.kind == t2::ParseResult::Kind::kNeedMore) {
    if (r.needed <= size) return "kNeedMore although enough bytes were given";
    if (r.needed > t2::kMaxPayloadBytes + t2::kMinPacketBytes) return "asks for an oversize packet";
  } else if (r.error.empty()) {
    return "error without a message";
  }
  // 2. The strict decoder either returns a packet or throws ProtocolError with a message.
  try {
    t2::decode(data, size);
  } catch (const t2::ProtocolError& e) {
    if (std::string(e.what()).empty()) return "ProtocolError without a message";
  }
  // 3. The emulator answers anything with well-formed packets only.
  Tau2Emulator emulator;
  const std::vector<uint8_t> out = emulator.feed(data, size);
  size_t offset = 0;
  while (offset < out.size()) {
    const t2::ParseResult p = t2::parse(out.data() + offset, out.size() - offset);
    if (p.kind != t2::ParseResult::Kind::kPacket)
      return "emulator sent a malformed reply: " + p.error;
    offset += p.consumed;
  }
  return {};
}

}  // namespace rgbdt::thermal_camera::fuzz
