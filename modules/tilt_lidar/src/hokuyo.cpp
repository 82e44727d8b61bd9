#include "rgbdt/tilt_lidar/hokuyo.hpp"

#include <mrpt/comms/CClientTCPSocket.h>
#include <mrpt/hwdrivers/CHokuyoURG.h>

#include <csignal>

#include "rgbdt/core/log.hpp"

namespace rgbdt::tilt_lidar {

/// MRPT's driver with two additions. When its socket has been closed by the peer, the
/// driver's own reconnect (inside doProcessSimple) connects and immediately writes with an
/// unbounded wait, which never returns if the device is still away; so the loss is detected
/// here first and the driver is recreated instead. drop_stream() lets the destructor skip
/// talking to a device that is gone.
class GuardedHokuyo : public mrpt::hwdrivers::CHokuyoURG {
 public:
  bool stream_lost() {
    auto* socket = dynamic_cast<mrpt::comms::CClientTCPSocket*>(m_stream.get());
    return socket != nullptr && !socket->isConnected();
  }
  void drop_stream() { m_stream.reset(); }
};

std::string HokuyoOptions::validate() const {
  if (ip_address.empty() && serial_port.empty()) return "either ip_address or serial_port must be set";
  if (!ip_address.empty() && (port <= 0 || port > 65535)) return "port " + std::to_string(port) + " must be in 1..65535";
  if (sensor_label.empty()) return "sensor_label must not be empty";
  if (!(silence_timeout_s > 0)) return "silence_timeout_s must be positive";
  return {};
}

HokuyoScanner::HokuyoScanner(const HokuyoOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("HokuyoScanner: " + why);
}

HokuyoScanner::~HokuyoScanner() {
  // The driver's destructor switches the laser off; with the connection gone that would
  // start a reconnect that can block (see GuardedHokuyo).
  if (driver_ && (restart_ || driver_->stream_lost())) driver_->drop_stream();
}

bool HokuyoScanner::start() {
  // MRPT's CClientTCPSocket writes without MSG_NOSIGNAL: a write to a scanner that has just
  // gone away would raise SIGPIPE and kill the process. Ignore it unless the application
  // installed its own handler.
  struct sigaction old {};
  if (::sigaction(SIGPIPE, nullptr, &old) == 0 && old.sa_handler == SIG_DFL) {
    std::signal(SIGPIPE, SIG_IGN);
    core::log_debug("hokuyo: SIGPIPE is now ignored (socket writes to a lost scanner)");
  }
  if (driver_) driver_->drop_stream();
  driver_ = std::make_unique<GuardedHokuyo>();
  auto& d = *driver_;
  // MRPT's driver logs to the console by default; a library must not print.
  d.logging_enable_console_output = false;
  d.logRegisterCallback([this](std::string_view msg, const mrpt::system::VerbosityLevel level, std::string_view,
                               const mrpt::Clock::time_point) {
    const core::LogLevel l = level >= mrpt::system::LVL_ERROR  ? core::LogLevel::kError
                             : level == mrpt::system::LVL_WARN ? core::LogLevel::kWarning
                             : level == mrpt::system::LVL_INFO ? core::LogLevel::kDebug  // device banners
                                                               : core::LogLevel::kDebug;
    std::string m(msg);
    while (!m.empty() && (m.back() == '\n' || m.back() == '\r')) m.pop_back();
    if (l >= core::LogLevel::kError) last_error_ = m;
    core::log_at(l, "hokuyo: ", m);
  });
  d.setSensorLabel(options_.sensor_label);
  d.setIntensityMode(options_.intensity);
  if (!options_.ip_address.empty()) d.setIPandPort(options_.ip_address, static_cast<unsigned>(options_.port));
  else d.setSerialPort(options_.serial_port);
  const std::string where =
      options_.ip_address.empty() ? options_.serial_port : options_.ip_address + ":" + std::to_string(options_.port);
  try {
    if (!d.turnOn()) {
      if (last_error_.empty()) last_error_ = where + ": the scanner did not answer the SCIP 2.0 start-up";
      return false;
    }
  } catch (const std::exception& e) {
    last_error_ = where + ": " + e.what();
    return false;
  }
  last_error_.clear();
  last_scan_ = std::chrono::steady_clock::now();
  restart_ = false;
  return true;
}

HokuyoScanner::Poll HokuyoScanner::poll(mrpt::obs::CObservation2DRangeScan& scan) {
  if (driver_ && !restart_ && driver_->stream_lost()) {
    last_error_ = "connection closed by the scanner";
    restart_ = true;
    return Poll::kDeviceError;
  }
  if (restart_ || !driver_) {
    if (driver_) driver_->drop_stream();  // closes the socket; no goodbye to a lost device
    driver_.reset();
    if (!start()) {
      restart_ = true;
      return Poll::kDeviceError;
    }
  }
  bool have = false, hw_error = false;
  try {
    driver_->doProcessSimple(have, scan, hw_error);
  } catch (const std::exception& e) {
    last_error_ = e.what();
    return Poll::kDeviceError;
  }
  const auto now = std::chrono::steady_clock::now();
  if (have && !hw_error) {
    last_scan_ = now;
    return Poll::kScan;
  }
  if (std::chrono::duration<double>(now - last_scan_).count() > options_.silence_timeout_s) {
    last_error_ = "no scan for " + std::to_string(options_.silence_timeout_s) + " s";
    restart_ = true;
    return Poll::kDeviceError;
  }
  return hw_error ? Poll::kDeviceError : Poll::kNoData;
}

}  // namespace rgbdt::tilt_lidar
