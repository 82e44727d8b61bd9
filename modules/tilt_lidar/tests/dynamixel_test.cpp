#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <thread>

#include "rgbdt/core/error.hpp"
#include "rgbdt/tilt_lidar/dynamixel.hpp"
#include "rgbdt/tilt_lidar/dynamixel_emulator.hpp"
#include "rgbdt/tilt_lidar/serial_port.hpp"

namespace rgbdt::tilt_lidar::dxl {
namespace {

using Bytes = std::vector<std::uint8_t>;

TEST(DynamixelPacket, Crc16MatchesTheReferenceValues) {
  // CRC-16 with polynomial 0x8005, init 0 (CRC-16/BUYPASS): check value of "123456789".
  const std::string check = "123456789";
  EXPECT_EQ(crc16(reinterpret_cast<const std::uint8_t*>(check.data()), check.size()), 0xFEE8);
  // ROBOTIS e-manual, Protocol 2.0 ping example: FF FF FD 00 01 03 00 01 | 19 4E.
  EXPECT_EQ(encode({1, kPing, 0, {}}), (Bytes{0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E}));
  // ... and its status reply (model 1030, firmware 38): ... 55 00 06 04 26 | 65 5D.
  EXPECT_EQ(encode({1, kStatus, 0, {0x06, 0x04, 0x26}}),
            (Bytes{0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D}));
}

TEST(DynamixelPacket, ByteStuffingRoundTrips) {
  const Packet p{3, kWrite, 0, {0x10, 0x00, 0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0xFF, 0xFD}};
  const Bytes bytes = encode(p);
  // Two FF FF FD runs inside the params: two stuffed FD bytes, LEN = 1 + 9 + 2 + 2.
  EXPECT_EQ(bytes[5], 14);
  EXPECT_EQ(bytes.size(), 7u + 14u);
  PacketParser parser;
  parser.feed(bytes.data(), bytes.size());
  const auto back = parser.next();
  ASSERT_TRUE(back);
  EXPECT_EQ(back->id, 3);
  EXPECT_EQ(back->instruction, kWrite);
  EXPECT_EQ(back->params, p.params);
}

TEST(DynamixelPacket, ParserSkipsGarbageAndCorruptPackets) {
  std::mt19937 rng(11);
  Bytes stream;
  std::vector<Packet> sent;
  int corrupted = 0;
  for (int k = 0; k < 200; ++k) {
    for (int g = 0; g < static_cast<int>(rng() % 5); ++g) stream.push_back(static_cast<std::uint8_t>(rng() % 0xFD));
    Packet p{static_cast<std::uint8_t>(rng() % 253), kStatus, static_cast<std::uint8_t>(rng() % 2), {}};
    for (int n = 0; n < static_cast<int>(rng() % 12); ++n) p.params.push_back(static_cast<std::uint8_t>(rng()));
    Bytes b = encode(p);
    if (k % 10 == 7) {
      b[b.size() - 3] ^= 0x40;  // corrupt a payload byte: CRC mismatch
      ++corrupted;
    } else {
      sent.push_back(p);
    }
    stream.insert(stream.end(), b.begin(), b.end());
  }
  PacketParser parser;
  std::vector<Packet> got;
  for (std::size_t pos = 0; pos < stream.size();) {
    const std::size_t n = std::min<std::size_t>(stream.size() - pos, 1 + rng() % 40);
    parser.feed(stream.data() + pos, n);
    pos += n;
    while (auto p = parser.next()) got.push_back(*p);
  }
  ASSERT_EQ(got.size(), sent.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].id, sent[k].id);
    EXPECT_EQ(got[k].error, sent[k].error);
    EXPECT_EQ(got[k].params, sent[k].params);
  }
  EXPECT_EQ(parser.crc_errors(), corrupted);
}

TEST(DynamixelPacket, LittleEndianHelpers) {
  EXPECT_EQ(le_bytes(-2, 4), (Bytes{0xFE, 0xFF, 0xFF, 0xFF}));
  const Bytes b{0xFE, 0xFF, 0xFF, 0xFF};
  EXPECT_EQ(from_le(b.data(), 4, true), -2);
  EXPECT_EQ(from_le(b.data(), 4, false), 0xFFFFFFFE);
}

TEST(DynamixelBus, PingReadWriteAndSyncReadOverAPseudoTerminal) {
  EmulatedMotorOptions mo;
  mo.id = 4;
  EmulatedMotor motor(mo);
  SerialPort port(motor.device());
  DynamixelBus bus(port);
  const auto ping = bus.ping(4);
  EXPECT_EQ(ping.model, 54024);
  EXPECT_EQ(ping.firmware, 38);
  const ControlTable t;
  bus.write(4, t.goal_velocity, le_bytes(12345, 4));
  const Bytes v = bus.read(4, t.goal_velocity, 4);
  EXPECT_EQ(from_le(v.data(), 4, true), 12345);
  const auto all = bus.sync_read({4}, t.goal_velocity, 4);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0], v);
  // An address past the table: the motor answers with an access error.
  try {
    bus.read(4, 1020, 8);
    FAIL() << "no error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("access error"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("id 4"), std::string::npos) << e.what();
  }
  // Nobody at id 9: timeouts, then a clear error.
  EXPECT_THROW(bus.ping(9), core::Error);
}

TEST(DynamixelBus, RetriesThroughDroppedAndCorruptReplies) {
  EmulatedMotor motor;
  SerialPort port(motor.device());
  BusOptions bo;
  // An attempt fails with p = 1 - 0.75^2 = 0.44; all 7 attempts with 0.44^7 = 0.3%. The
  // emulator's fault sequence is seeded, so the run is reproducible.
  bo.retries = 6;
  DynamixelBus bus(port, bo);
  motor.set_drop_probability(0.25);
  motor.set_corrupt_probability(0.25);
  int ok = 0;
  for (int k = 0; k < 100; ++k) {
    try {
      bus.read(1, ControlTable{}.present_position, 4);
      ++ok;
    } catch (const core::Error&) {
    }
  }
  EXPECT_EQ(ok, 100);
  EXPECT_GT(bus.stats().retries, 20);
  EXPECT_GT(bus.stats().crc_errors, 10);
  EXPECT_GT(bus.stats().timeouts, 10);

  motor.set_drop_probability(0);
  motor.set_corrupt_probability(0);
  motor.set_silent(true);
  try {
    bus.ping(1);
    FAIL() << "silent motor answered";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("no valid reply"), std::string::npos) << e.what();
  }
  motor.set_silent(false);
  EXPECT_EQ(bus.ping(1).model, 54024);
}

TEST(SweepController, SweepsBetweenTheLimitsAtTheSetSpeed) {
  EmulatedMotor motor;
  SerialPort port(motor.device());
  DynamixelBus bus(port);
  SweepOptions so;
  so.lower_rad = -0.2;
  so.upper_rad = 0.2;
  so.speed_rad_s = 1.0;
  const auto t0 = std::chrono::steady_clock::now();
  auto clock = [t0] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  SweepController sweep(bus, so, clock);
  sweep.start();
  std::vector<SweepController::Reading> readings;
  int turns = 0, dir = sweep.direction();
  // 0 -> 0.2 -> -0.2 -> 0.2 takes ~1 s at 1 rad/s; run until the second turn has been
  // ridden out (with a generous limit: on a loaded machine each round trip is slower).
  double second_turn_s = -1.0;
  while (clock() < 8.0 && (second_turn_s < 0 || clock() < second_turn_s + 0.15)) {
    if (auto r = sweep.step()) readings.push_back(*r);
    if (sweep.direction() != dir) {
      dir = sweep.direction();
      if (++turns == 2) second_turn_s = clock();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(4));
  }
  sweep.stop();
  ASSERT_GE(turns, 2);
  ASSERT_GT(readings.size(), 20u);
  double lo = 1e9, hi = -1e9;
  std::vector<double> speeds;
  for (std::size_t k = 1; k < readings.size(); ++k) {
    const auto& a = readings[k - 1].sample;
    const auto& b = readings[k].sample;
    EXPECT_GT(b.time_s, a.time_s);
    lo = std::min(lo, b.angle_rad);
    hi = std::max(hi, b.angle_rad);
    // Cruise: both readings in the middle of the sweep, away from the decelerations.
    if (std::abs(a.angle_rad) < 0.12 && std::abs(b.angle_rad) < 0.12 && b.time_s - a.time_s > 0.003) {
      speeds.push_back(std::abs(b.angle_rad - a.angle_rad) / (b.time_s - a.time_s));
    }
  }
  // The motor decelerates into each limit (a = 40 rad/s^2), so it reaches it within the
  // turn tolerance and overshoots by less than v^2 / 2a = 0.0125 rad.
  EXPECT_GT(hi, so.upper_rad - 0.01);
  EXPECT_LT(hi, so.upper_rad + 0.0125);
  EXPECT_LT(lo, so.lower_rad + 0.01);
  EXPECT_GT(lo, so.lower_rad - 0.0125);
  // Cruise speed is the set speed. Each stamp is the midpoint of a round trip, so a speed
  // from two stamps carries their jitter; the median over the cruise is within 20%.
  ASSERT_GE(speeds.size(), 5u);
  std::nth_element(speeds.begin(), speeds.begin() + speeds.size() / 2, speeds.end());
  EXPECT_NEAR(speeds[speeds.size() / 2], so.speed_rad_s, 0.2);
}

}  // namespace
}  // namespace rgbdt::tilt_lidar::dxl
