#pragma once
// The bodies of the fuzz targets, shared by the libFuzzer programs and by the gtest that
// replays the regression corpus. Each returns the number of packets/responses accepted and
// aborts only if an invariant breaks.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include <unistd.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/tilt_lidar/dynamixel.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"
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

// Arbitrary bytes as a rawlog file (plain or gzip): read every observation, convert the
// scans and encoder samples, and replay them into an assembler. Unreadable input must end
// in rgbdt::core::Error or a reported truncation; any other exception, a crash or an
// allocation beyond the input's size is a bug. Returns the observations read.
inline int rawlog_input(const std::uint8_t* data, std::size_t size) {
  static const std::string path = "/tmp/rgbdt_rawlog_fuzz_" + std::to_string(::getpid()) + ".rawlog";
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) std::abort();
    if (size && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
  }
  int observations = 0;
  try {
    RawlogReader reader(path);
    while (auto obs = reader.next()) {
      ++observations;
      if (const auto* scan = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(obs.get())) {
        const Scan sc = from_observation(*scan);
        if (sc.ranges_m.size() != scan->getScanSize() || sc.valid.size() != sc.ranges_m.size()) std::abort();
        for (std::size_t i = 0; i < sc.ranges_m.size(); ++i)
          if (sc.valid[i] && !(sc.ranges_m[i] >= 0.0f)) std::abort();  // NaN/negative must be invalid
      } else if (const auto* daq = dynamic_cast<const mrpt::obs::CObservationRawDAQ*>(obs.get())) {
        try {
          from_observation(*daq, core::TiltRig{}.motor);
        } catch (const core::Error&) {
        }
      }
    }
    if (reader.truncated() && reader.error().find(path) == std::string::npos) std::abort();
  } catch (const core::Error& e) {
    if (std::string(e.what()).find(path) == std::string::npos) std::abort();  // must name the file
  }
  try {
    Assembler assembler(core::TiltRig{});
    replay_rawlog(path, assembler, [](TiltCloud&&) {}, StreamLabels{});
  } catch (const core::Error&) {
  }
  std::remove(path.c_str());
  return observations;
}

}  // namespace rgbdt::tilt_lidar::fuzz
