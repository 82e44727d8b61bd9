#pragma once
/// \file
/// Dynamixel Protocol 2.0 (the tilt motor, a Dynamixel PRO), split in three layers:
///  - packets: framing FF FF FD 00 | ID | LEN(2, LE) | INST | PARAMS | CRC(2, LE), byte
///    stuffing (FF FF FD -> FF FF FD FD inside INST+PARAMS), CRC-16 with polynomial 0x8005;
///    encoding and an incremental parser that resynchronises on garbage (no I/O);
///  - DynamixelBus: ping/read/write/sync read over any ByteTransport, with timeouts and
///    retries, every failure reported with the motor id and what went wrong;
///  - SweepController: sweeps the tilt between two limits at a set speed and returns
///    time-stamped encoder readings for the Assembler.
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/tilt_lidar/assembler.hpp"

namespace rgbdt::tilt_lidar::dxl {

enum Instruction : std::uint8_t {
  kPing = 0x01, kRead = 0x02, kWrite = 0x03, kRegWrite = 0x04, kAction = 0x05,
  kReboot = 0x08, kStatus = 0x55, kSyncRead = 0x82, kSyncWrite = 0x83,
};
constexpr std::uint8_t kBroadcastId = 0xFE;

/// CRC-16 of Protocol 2.0 (polynomial 0x8005, initial value 0, no reflection).
std::uint16_t crc16(const std::uint8_t* data, std::size_t size, std::uint16_t crc = 0);

struct Packet {
  std::uint8_t id = 0;
  std::uint8_t instruction = 0;
  std::uint8_t error = 0;            ///< status packets only (bit 7 = hardware alert)
  std::vector<std::uint8_t> params;  ///< unstuffed; for status packets without the error byte
};

/// Encodes an instruction packet (or a status packet when instruction == kStatus, then
/// `error` is written before the params). Applies byte stuffing and the CRC.
std::vector<std::uint8_t> encode(const Packet& packet);

/// Incremental packet parser (used on both sides of the bus).
class PacketParser {
 public:
  void feed(const std::uint8_t* data, std::size_t size);
  /// The next valid packet, if complete. Corrupt packets (bad CRC, impossible length) are
  /// skipped and counted; parsing restarts at the next header.
  std::optional<Packet> next();
  std::int64_t crc_errors() const { return crc_errors_; }
  std::int64_t framing_errors() const { return framing_errors_; }
  std::size_t buffered() const { return buffer_.size(); }
  void clear() { buffer_.clear(); }

  static constexpr std::size_t kMaxLength = 1024;  ///< longer LEN fields are framing errors

 private:
  std::vector<std::uint8_t> buffer_;
  std::int64_t crc_errors_ = 0, framing_errors_ = 0;
};

/// Little-endian helpers for control-table values.
std::vector<std::uint8_t> le_bytes(std::int64_t value, int size);
std::int64_t from_le(const std::uint8_t* data, int size, bool is_signed);

/// Bytes in and out; implemented by SerialPort and by tests.
class ByteTransport {
 public:
  virtual ~ByteTransport() = default;
  virtual void write(const std::uint8_t* data, std::size_t size) = 0;
  /// Reads what is available, waiting at most timeout_ms for the first byte; 0 = timeout.
  virtual std::size_t read(std::uint8_t* data, std::size_t size, int timeout_ms) = 0;
  virtual void discard_input() = 0;
};

/// Control-table addresses and units. Defaults: Dynamixel PRO H54-200-S500-R.
struct ControlTable {
  std::uint16_t torque_enable = 562;     ///< 1 byte
  std::uint16_t goal_position = 596;     ///< 4 bytes, signed counts
  std::uint16_t goal_velocity = 600;     ///< 4 bytes, signed, velocity units
  std::uint16_t present_position = 611;  ///< 4 bytes, signed counts
  std::uint16_t present_velocity = 615;  ///< 4 bytes
  double counts_per_revolution = 501923.0;  ///< H54-200: +-250961 counts per half turn
  double rpm_per_velocity_unit = 0.00199234;
};

struct BusOptions {
  int timeout_ms = 20;  ///< per attempt; a PRO at 1 Mbaud answers in < 1 ms
  int retries = 2;      ///< extra attempts after a timeout or a corrupt reply
  std::string validate() const;
};

struct BusStats {
  std::int64_t requests = 0, timeouts = 0, crc_errors = 0, retries = 0, failures = 0;
};

/// Protocol 2.0 client. Every call throws rgbdt::core::Error (naming the id, the
/// instruction and the cause) when all attempts fail, or when the motor reports an error.
class DynamixelBus {
 public:
  DynamixelBus(ByteTransport& transport, const BusOptions& options = {});

  /// Model number and firmware version.
  struct PingReply {
    std::uint16_t model = 0;
    std::uint8_t firmware = 0;
  };
  PingReply ping(std::uint8_t id);
  std::vector<std::uint8_t> read(std::uint8_t id, std::uint16_t address, std::uint16_t length);
  void write(std::uint8_t id, std::uint16_t address, const std::vector<std::uint8_t>& data);
  /// One read of the same item from several motors; replies in id order. Throws if any
  /// motor does not answer.
  std::vector<std::vector<std::uint8_t>> sync_read(const std::vector<std::uint8_t>& ids, std::uint16_t address,
                                                   std::uint16_t length);
  const BusStats& stats() const { return stats_; }

 private:
  Packet transact(const Packet& request, const char* what);
  std::optional<Packet> receive_from(std::uint8_t id, int timeout_ms);

  ByteTransport& transport_;
  BusOptions options_;
  PacketParser parser_;
  BusStats stats_;
};

struct SweepOptions {
  std::uint8_t id = 1;
  double lower_rad = -0.35;   ///< sweep limits (tilt angle, tilt_rig.hpp sign)
  double upper_rad = 0.35;
  double speed_rad_s = 1.2;   ///< ~600 ms per 40-degree tilt (design.md)
  double turn_tolerance_rad = 0.005;  ///< this close to a limit counts as reached
  ControlTable table;
  std::string validate() const;
};

/// Sweeps the motor between two limits. Call step() in a loop (e.g. at 200 Hz): each call
/// reads the present position once, stamps it with the midpoint of request and reply,
/// and turns the motor around at the limits.
class SweepController {
 public:
  using Clock = std::function<double()>;  ///< seconds, the recording clock

  SweepController(DynamixelBus& bus, const SweepOptions& options, Clock clock);
  /// Enables torque, sets the velocity and sends the first goal. Throws core::Error.
  void start();
  /// One reading; nullopt if the motor did not answer (counted in the bus stats).
  struct Reading {
    EncoderSample sample;      ///< angle from the motor's counts
    std::int64_t count = 0;    ///< raw present position
  };
  std::optional<Reading> step();
  /// Disables torque (best effort).
  void stop();
  int direction() const { return direction_; }

  /// count <-> angle with the control table's resolution, zero count = angle 0.
  double angle_from_count(std::int64_t count) const;
  std::int64_t count_from_angle(double angle_rad) const;

 private:
  void send_goal(double angle_rad);

  DynamixelBus& bus_;
  SweepOptions options_;
  Clock clock_;
  int direction_ = 1;
};

}  // namespace rgbdt::tilt_lidar::dxl
