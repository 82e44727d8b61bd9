#pragma once
/// \file
/// An emulated Hokuyo UTM-30LX speaking SCIP 2.0 on a loopback TCP port, for tests and
/// demos without the device: MRPT's own CHokuyoURG driver connects to it.
///
/// The protocol side (ScipDevice) is transport-free: it turns command lines into response
/// bytes and builds streamed scan messages. HokuyoEmulator adds the TCP server (127.0.0.1
/// only), the scan clock and a callback that supplies the ranges (e.g. from a simulator).
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "rgbdt/tilt_lidar/scip.hpp"

namespace rgbdt::tilt_lidar {

/// What the emulated device reports in PP/VV (UTM-30LX values).
struct EmulatedDeviceSpec {
  std::string model = "UTM-30LX";
  int range_min_mm = 23, range_max_mm = 60000;
  int steps_per_revolution = 1440;  ///< ARES
  int first_step = 0, last_step = 1080, front_step = 540;
  int motor_rpm = 2400;             ///< 25 ms per scan
  std::string serial = "H0000000";
  int beams() const { return last_step - first_step + 1; }
};

/// SCIP 2.0 device state machine: no I/O.
class ScipDevice {
 public:
  explicit ScipDevice(EmulatedDeviceSpec spec = {}) : spec_(std::move(spec)) {}

  /// Response bytes to one command line (without its LF). Unknown commands get status "0E".
  std::string handle(const std::string& line);
  /// True while an MD/ME command is active (until QT or the requested scan count).
  bool streaming() const { return streaming_; }
  /// Number of beams of the active measurement command.
  int measurement_beams() const { return command_.end_step - command_.start_step + 1; }
  bool measurement_intensity() const { return command_.intensity; }
  /// One streamed scan: echo of the active command, status 99, timestamp and data.
  /// `frame` must hold measurement_beams() ranges. Ends streaming after the last of a
  /// finite scan count.
  std::string scan_message(const scip::ScanFrame& frame);
  const EmulatedDeviceSpec& spec() const { return spec_; }

 private:
  EmulatedDeviceSpec spec_;
  bool laser_on_ = false;
  bool streaming_ = false;
  scip::MeasurementCommand command_;
  std::string command_line_;
  int scans_left_ = 0;
};

/// Ranges of one emulated scan (measurement_beams() values, mm; < 20 = no return).
/// `index` counts scans since start(), `time_s` is the emulator's clock (seconds since
/// start(), the same clock as the device timestamp).
using RangeSource = std::function<scip::ScanFrame(std::int64_t index, double time_s)>;

struct HokuyoEmulatorOptions {
  int port = 0;                 ///< TCP port on 127.0.0.1; 0 picks a free one in 20000-31999
  double scan_period_s = 0.025; ///< UTM-30LX: 40 scans/s
  std::size_t keep_served = 4096;  ///< served scans remembered for tests
  EmulatedDeviceSpec device;
  std::string validate() const;
};

class HokuyoEmulator {
 public:
  struct Served {
    std::int64_t index = 0;
    scip::ScanFrame frame;
  };

  HokuyoEmulator(RangeSource source, HokuyoEmulatorOptions options = {});
  ~HokuyoEmulator();
  HokuyoEmulator(const HokuyoEmulator&) = delete;
  HokuyoEmulator& operator=(const HokuyoEmulator&) = delete;

  /// Listens on 127.0.0.1 (the same port again after stop(), so a driver can reconnect).
  /// Throws rgbdt::core::Error if the port cannot be bound.
  void start();
  /// Closes the listening and client sockets: to a client the device disappears.
  void stop();
  bool running() const { return running_; }
  int port() const { return port_; }
  std::int64_t scans_sent() const { return scans_sent_; }
  std::int64_t connections() const { return connections_; }
  /// The most recent served scans (up to keep_served), oldest first.
  std::deque<Served> served() const;

 private:
  void run();
  void serve_client(int fd);

  RangeSource source_;
  HokuyoEmulatorOptions options_;
  int port_ = 0;
  int listen_fd_ = -1;
  std::atomic<bool> running_{false};
  std::atomic<std::int64_t> scans_sent_{0};
  std::atomic<std::int64_t> connections_{0};
  std::int64_t next_index_ = 0;
  std::thread thread_;
  mutable std::mutex mutex_;
  std::deque<Served> served_;
  double t0_ = 0.0;  // steady-clock seconds at the first start()
};

}  // namespace rgbdt::tilt_lidar
