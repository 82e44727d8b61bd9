#include "rgbdt/tilt_lidar/hokuyo.hpp"

#include <mrpt/hwdrivers/CHokuyoURG.h>

#include "rgbdt/core/log.hpp"

namespace rgbdt::tilt_lidar {

std::string HokuyoOptions::validate() const {
  if (ip_address.empty() && serial_port.empty()) return "either ip_address or serial_port must be set";
  if (!ip_address.empty() && (port <= 0 || port > 65535)) return "port " + std::to_string(port) + " must be in 1..65535";
  if (sensor_label.empty()) return "sensor_label must not be empty";
  return {};
}

HokuyoScanner::HokuyoScanner(const HokuyoOptions& options) : options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("HokuyoScanner: " + why);
}

HokuyoScanner::~HokuyoScanner() = default;

bool HokuyoScanner::start() {
  driver_ = std::make_unique<mrpt::hwdrivers::CHokuyoURG>();
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
  return true;
}

HokuyoScanner::Poll HokuyoScanner::poll(mrpt::obs::CObservation2DRangeScan& scan) {
  if (!driver_) return Poll::kDeviceError;
  bool have = false, hw_error = false;
  try {
    driver_->doProcessSimple(have, scan, hw_error);
  } catch (const std::exception& e) {
    last_error_ = e.what();
    return Poll::kDeviceError;
  }
  if (hw_error) return Poll::kDeviceError;
  return have ? Poll::kScan : Poll::kNoData;
}

}  // namespace rgbdt::tilt_lidar
