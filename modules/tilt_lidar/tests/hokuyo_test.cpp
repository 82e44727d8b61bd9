#include <gtest/gtest.h>

#include <chrono>
#include <random>
#include <thread>

#include "rgbdt/tilt_lidar/hokuyo.hpp"
#include "rgbdt/tilt_lidar/hokuyo_emulator.hpp"
#include "rgbdt/tilt_lidar/scip.hpp"

namespace rgbdt::tilt_lidar {
namespace {

using namespace std::chrono_literals;

TEST(Scip, EncodingMatchesTheProtocolExamples) {
  // SCIP 2.0 specification examples: "CB" = 1234 (2 chars), "1Dh" = 5432 (3 chars).
  EXPECT_EQ(scip::encode(1234, 2), "CB");
  EXPECT_EQ(scip::encode(5432, 3), "1Dh");
  EXPECT_EQ(*scip::decode("CB"), 1234u);
  EXPECT_EQ(*scip::decode("1Dh"), 5432u);
  EXPECT_EQ(*scip::decode(scip::encode(16777215, 4)), 16777215u);
  EXPECT_THROW(scip::encode(4096, 2), std::invalid_argument);
  EXPECT_FALSE(scip::decode("1D\x7f"));
  EXPECT_FALSE(scip::decode(""));
  // Status checksums seen on real devices: "00P" and "99b".
  EXPECT_EQ(scip::checksum("00"), 'P');
  EXPECT_EQ(scip::checksum("99"), 'b');
}

TEST(Scip, ParserReassemblesResponsesFromArbitraryChunks) {
  ScipDevice dev;
  std::string bytes = dev.handle("BM");  // one statement each: the device's state matters
  bytes += dev.handle("PP");
  bytes += dev.handle("MD0000108001000");
  scip::ScanFrame f;
  f.timestamp_ms = 123456;
  for (int i = 0; i < 1081; ++i) f.ranges_mm.push_back(static_cast<std::uint32_t>(20 + i * 37));
  bytes += dev.scan_message(f);
  std::mt19937 rng(3);
  scip::ResponseParser p;
  std::vector<scip::Response> got;
  for (std::size_t pos = 0; pos < bytes.size();) {
    const std::size_t n = std::min<std::size_t>(bytes.size() - pos, 1 + rng() % 200);
    p.feed(std::string_view(bytes).substr(pos, n));
    pos += n;
    while (auto r = p.next()) got.push_back(*r);
  }
  EXPECT_TRUE(p.take_errors().empty());
  ASSERT_EQ(got.size(), 4u);
  EXPECT_EQ(got[0].echo, "BM");
  EXPECT_EQ(got[0].status, "00");
  EXPECT_EQ(got[1].lines.size(), 8u);
  EXPECT_EQ(got[1].lines[2], "DMAX:60000;");
  EXPECT_EQ(got[3].status, "99");
  const auto frame = scip::decode_scan_lines(got[3].lines, 1081, false);
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->timestamp_ms, 123456u);
  EXPECT_EQ(frame->ranges_mm, f.ranges_mm);
}

TEST(Scip, BadChecksumIsReportedAndTheParserResynchronises) {
  ScipDevice dev;
  std::string bad = dev.handle("PP");
  bad[bad.find("DMAX:60000;") + 11] ^= 0x01;  // corrupt that line's checksum char
  scip::ResponseParser p;
  p.feed(bad + dev.handle("BM"));
  const auto r = p.next();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->echo, "BM");  // the corrupt PP response was skipped
  const auto errors = p.take_errors();
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("checksum"), std::string::npos) << errors[0];
  EXPECT_NE(errors[0].find("PP"), std::string::npos) << errors[0];
}

TEST(Scip, DecodeRejectsWrongLengthsAndUnknownCommands) {
  std::string why;
  EXPECT_FALSE(scip::decode_scan_lines({"0000", "000"}, 2, false, &why));
  EXPECT_NE(why.find("expected 6"), std::string::npos) << why;
  ScipDevice dev;
  EXPECT_EQ(dev.handle("XX"), "XX\n0Ee\n\n");  // status "0E" + its checksum
  EXPECT_FALSE(scip::parse_measurement_command("MD00001080010"));
  const auto c = scip::parse_measurement_command("ME0044072501105");
  ASSERT_TRUE(c);
  EXPECT_TRUE(c->intensity);
  EXPECT_EQ(c->start_step, 44);
  EXPECT_EQ(c->end_step, 725);
  EXPECT_EQ(c->scans, 5);
}

// Beam 0 carries the scan index so a received scan can be matched to the served one.
scip::ScanFrame indexed_scan(std::int64_t index, double) {
  scip::ScanFrame f;
  f.ranges_mm.resize(1081);
  f.ranges_mm[0] = static_cast<std::uint32_t>(30000 + index);
  for (int i = 1; i < 1081; ++i) f.ranges_mm[i] = static_cast<std::uint32_t>(100 + (index * 7 + i * 13) % 29000);
  f.ranges_mm[5] = 0;  // no return
  return f;
}

bool same_as_served(const mrpt::obs::CObservation2DRangeScan& obs, const std::deque<HokuyoEmulator::Served>& served,
                    std::int64_t* index) {
  const auto id = static_cast<std::int64_t>(std::lround(obs.getScanRange(0) * 1000.0f)) - 30000;
  for (const auto& s : served) {
    if (s.index != id) continue;
    *index = id;
    if (obs.getScanSize() != s.frame.ranges_mm.size()) return false;
    for (std::size_t i = 0; i < obs.getScanSize(); ++i) {
      const std::uint32_t mm = s.frame.ranges_mm[i];
      // MRPT stores mm * 0.001f; valid iff >= 20 mm and within DMAX.
      if (std::abs(obs.getScanRange(i) - mm * 0.001f) > 1e-6f) return false;
      if (obs.getScanRangeValidity(i) != (mm >= 20)) return false;
    }
    return true;
  }
  return false;
}

// Real-time socket test: timing under sanitizers is fine (scans are paced by the emulator).
TEST(HokuyoEmulator, MrptCHokuyoUrgReceivesTheServedScans) {
  HokuyoEmulator emu(indexed_scan);
  emu.start();
  HokuyoOptions opt;
  opt.ip_address = "127.0.0.1";
  opt.port = emu.port();
  HokuyoScanner scanner(opt);
  ASSERT_TRUE(scanner.start()) << scanner.last_error();
  int matched = 0;
  std::int64_t last = -1;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (matched < 20 && std::chrono::steady_clock::now() < deadline) {
    mrpt::obs::CObservation2DRangeScan obs;
    if (scanner.poll(obs) != HokuyoScanner::Poll::kScan) continue;
    std::int64_t index = -1;
    ASSERT_TRUE(same_as_served(obs, emu.served(), &index)) << "scan with beam0 " << obs.getScanRange(0);
    EXPECT_GT(index, last);  // in order, none repeated
    last = index;
    EXPECT_EQ(obs.sensorLabel, "HOKUYO");
    EXPECT_NEAR(obs.aperture, 1081 * 2 * M_PI / 1440, 1e-5);  // MRPT: beams * 2 pi / ARES
    ++matched;
  }
  EXPECT_EQ(matched, 20);
}

TEST(HokuyoEmulator, DriverReportsTheLossAndReconnectsWhenTheDeviceReturns) {
  HokuyoEmulator emu(indexed_scan);
  emu.start();
  HokuyoOptions opt;
  opt.ip_address = "127.0.0.1";
  opt.port = emu.port();
  HokuyoScanner scanner(opt);
  ASSERT_TRUE(scanner.start()) << scanner.last_error();
  auto poll_until = [&](HokuyoScanner::Poll want, std::chrono::seconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      mrpt::obs::CObservation2DRangeScan obs;
      if (scanner.poll(obs) == want) return true;
    }
    return false;
  };
  ASSERT_TRUE(poll_until(HokuyoScanner::Poll::kScan, 5s));
  emu.stop();
  EXPECT_TRUE(poll_until(HokuyoScanner::Poll::kDeviceError, 5s));
  emu.start();  // same port
  EXPECT_TRUE(poll_until(HokuyoScanner::Poll::kScan, 10s));
  EXPECT_GE(emu.connections(), 2);
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
