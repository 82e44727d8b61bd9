#pragma once
/// \file
/// An emulated Dynamixel PRO on a pseudo-terminal (openpty), for tests and demos: it
/// answers Protocol 2.0 ping/read/write/sync read on its control table and moves like a
/// real motor (trapezoidal profile: goal position, velocity limit from Goal Velocity,
/// finite acceleration). Faults can be injected: dropped replies, corrupt CRCs, silence.
#include <atomic>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rgbdt/tilt_lidar/dynamixel.hpp"

namespace rgbdt::tilt_lidar::dxl {

struct EmulatedMotorOptions {
  std::uint8_t id = 1;
  std::uint16_t model = 54024;          ///< H54-200-S500-R
  std::uint8_t firmware = 38;
  ControlTable table;
  double acceleration_rad_s2 = 40.0;    ///< turn-around in ~60 ms at 1.2 rad/s
  double max_speed_rad_s = 3.5;         ///< used when Goal Velocity is 0
  double initial_angle_rad = 0.0;
  unsigned seed = 1;                    ///< for the fault injection
};

class EmulatedMotor {
 public:
  /// Opens the pseudo-terminal and starts answering. Throws rgbdt::core::Error.
  explicit EmulatedMotor(const EmulatedMotorOptions& options = {});
  ~EmulatedMotor();
  EmulatedMotor(const EmulatedMotor&) = delete;
  EmulatedMotor& operator=(const EmulatedMotor&) = delete;

  /// Path of the serial device the driver opens (e.g. /dev/pts/7).
  const std::string& device() const { return device_; }

  void set_drop_probability(double p) { drop_probability_ = p; }      ///< reply not sent
  void set_corrupt_probability(double p) { corrupt_probability_ = p; }  ///< reply CRC flipped
  void set_silent(bool silent) { silent_ = silent; }                  ///< stops answering

  /// True motor state, for tests.
  double angle_rad();
  double velocity_rad_s();
  std::int64_t requests() const { return requests_; }
  std::int64_t crc_errors_seen() const { return crc_errors_seen_; }

 private:
  void run();
  void handle(const Packet& p);
  void advance(double now_s);
  void reply(const Packet& status);
  std::int64_t position_count() const;

  EmulatedMotorOptions options_;
  std::string device_;
  int master_fd_ = -1, slave_fd_ = -1;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<double> drop_probability_{0.0}, corrupt_probability_{0.0};
  std::atomic<bool> silent_{false};
  std::atomic<std::int64_t> requests_{0}, crc_errors_seen_{0};

  std::mutex mutex_;  // guards the motion state and the control table
  std::vector<std::uint8_t> memory_;
  double pos_rad_ = 0.0, vel_rad_s_ = 0.0, last_s_ = 0.0;
  unsigned rng_state_;
};

}  // namespace rgbdt::tilt_lidar::dxl
