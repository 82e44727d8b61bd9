#pragma once
// The bodies of the fuzz targets, shared by the libFuzzer programs and by the gtest that
// replays the regression corpus. Each returns the number of packets/responses accepted and
// aborts only if an invariant breaks.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "rgbdt/tilt_lidar/dynamixel.hpp"
#include "rgbdt/tilt_lidar/scip.hpp"

namespace rgbdt::tilt_lidar::fuzz {

inline int scip_input(const std::uint8_t* data, std::size_t size) {
  scip::ResponseParser parser;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  // Fed in two pieces to exercise reassembly at an input-dependent split.
  const std::size_t split = size ? data[0] % (size + 1) : 0;
  parser.feed(bytes.substr(0, split));
  parser.feed(bytes.substr(split));
  int accepted = 0;
  while (auto r = parser.next()) {
    ++accepted;
    if (r->status.size() != 2) std::abort();
    for (const bool intensity : {false, true}) scip::decode_scan_lines(r->lines, 1081, intensity);
    scip::decode_scan_lines(r->lines, static_cast<int>(r->lines.size()), false);
    scip::parse_measurement_command(r->echo);
    // What the parser accepted must survive re-encoding (except info lines, whose
    // checksum convention is ambiguous by design).
    scip::ResponseParser again;
    again.feed(scip::encode_response(*r));
    if (!again.next()) std::abort();
  }
  parser.take_errors();
  return accepted;
}

inline int dynamixel_input(const std::uint8_t* data, std::size_t size) {
  dxl::PacketParser parser;
  const std::size_t split = size ? data[0] % (size + 1) : 0;
  parser.feed(data, split);
  parser.feed(data + split, size - split);
  int accepted = 0;
  while (auto p = parser.next()) {
    ++accepted;
    const auto bytes = dxl::encode(*p);
    dxl::PacketParser again;
    again.feed(bytes.data(), bytes.size());
    const auto q = again.next();
    if (!q || q->id != p->id || q->instruction != p->instruction || q->params != p->params ||
        (p->instruction == dxl::kStatus && q->error != p->error)) {
      std::abort();  // round trip broken
    }
  }
  return accepted;
}

}  // namespace rgbdt::tilt_lidar::fuzz
