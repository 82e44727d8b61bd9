#pragma once
/// \file
/// The Hokuyo scanner through MRPT's own driver, mrpt::hwdrivers::CHokuyoURG (SCIP 2.0
/// over Ethernet or USB-serial). This class only configures the driver, routes its log
/// into rgbdt::core::log and reports scans, silence and device errors; reconnection after
/// the device disappears is first the driver's (it re-opens and re-initialises on its own
/// when polled again); if no scan arrives for silence_timeout_s the driver is recreated.
#include <chrono>
#include <memory>
#include <string>

#include <mrpt/obs/CObservation2DRangeScan.h>

namespace rgbdt::tilt_lidar {

class GuardedHokuyo;  // CHokuyoURG with loss detection (hokuyo.cpp)

struct HokuyoOptions {
  std::string ip_address = "192.168.0.10";  ///< Ethernet UTM-30LX default; empty = serial
  int port = 10940;                          ///< SCIP TCP port
  std::string serial_port;                   ///< e.g. /dev/ttyACM0 (when ip_address is empty)
  bool intensity = false;                    ///< ME instead of MD
  std::string sensor_label = "HOKUYO";       ///< tilt_rig.hpp raw-stream label
  /// No scan for this long while streaming = the device is gone: poll() reports an error
  /// and the next poll() restarts the driver (MRPT's own reconnect can stall on a peer
  /// that accepted the connection but never answers).
  double silence_timeout_s = 1.0;
  std::string validate() const;
};

class HokuyoScanner {
 public:
  enum class Poll { kScan, kNoData, kDeviceError };

  /// Throws std::invalid_argument for invalid options.
  explicit HokuyoScanner(const HokuyoOptions& options);
  ~HokuyoScanner();
  HokuyoScanner(const HokuyoScanner&) = delete;
  HokuyoScanner& operator=(const HokuyoScanner&) = delete;

  /// Connects, switches the laser on and starts streaming. false (and last_error()) if the
  /// device is unreachable or does not answer. Sets SIGPIPE to ignored if it still has its
  /// default action: MRPT's socket writes to a vanished scanner would otherwise kill the
  /// process.
  bool start();
  /// Waits for the next scan (a few tens of ms at most). kDeviceError while the device is
  /// unreachable; keep polling to let the driver reconnect.
  Poll poll(mrpt::obs::CObservation2DRangeScan& scan);
  const std::string& last_error() const { return last_error_; }
  const HokuyoOptions& options() const { return options_; }

 private:
  HokuyoOptions options_;
  std::unique_ptr<GuardedHokuyo> driver_;
  std::string last_error_;
  std::chrono::steady_clock::time_point last_scan_{};
  bool restart_ = false;
};

}  // namespace rgbdt::tilt_lidar
