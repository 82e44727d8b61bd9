#pragma once
/// \file
/// The Hokuyo scanner through MRPT's own driver, mrpt::hwdrivers::CHokuyoURG (SCIP 2.0
/// over Ethernet or USB-serial). This class only configures the driver, routes its log
/// into rgbdt::core::log and reports scans, silence and device errors; reconnection after
/// the device disappears is the driver's (it re-opens and re-initialises on its own when
/// polled again).
#include <memory>
#include <string>

#include <mrpt/obs/CObservation2DRangeScan.h>

namespace mrpt::hwdrivers {
class CHokuyoURG;
}

namespace rgbdt::tilt_lidar {

struct HokuyoOptions {
  std::string ip_address = "192.168.0.10";  ///< Ethernet UTM-30LX default; empty = serial
  int port = 10940;                          ///< SCIP TCP port
  std::string serial_port;                   ///< e.g. /dev/ttyACM0 (when ip_address is empty)
  bool intensity = false;                    ///< ME instead of MD
  std::string sensor_label = "HOKUYO";       ///< tilt_rig.hpp raw-stream label
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
  /// device is unreachable or does not answer.
  bool start();
  /// Waits for the next scan (a few tens of ms at most). kDeviceError while the device is
  /// unreachable; keep polling to let the driver reconnect.
  Poll poll(mrpt::obs::CObservation2DRangeScan& scan);
  const std::string& last_error() const { return last_error_; }
  const HokuyoOptions& options() const { return options_; }

 private:
  HokuyoOptions options_;
  std::unique_ptr<mrpt::hwdrivers::CHokuyoURG> driver_;
  std::string last_error_;
};

}  // namespace rgbdt::tilt_lidar
