#pragma once
/// \file
/// A raw serial port (termios) as a dxl::ByteTransport: 8N1, no flow control, no line
/// discipline. Works with USB-RS485 adapters and with pseudo-terminals.
#include <string>

#include "rgbdt/tilt_lidar/dynamixel.hpp"

namespace rgbdt::tilt_lidar {

class SerialPort : public dxl::ByteTransport {
 public:
  /// Opens and configures the port; throws rgbdt::core::Error naming the device and the
  /// system error. Baud rates: 9600 ... 4000000 (those termios knows).
  SerialPort(const std::string& device, int baud = 1000000);
  ~SerialPort() override;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  void write(const std::uint8_t* data, std::size_t size) override;
  std::size_t read(std::uint8_t* data, std::size_t size, int timeout_ms) override;
  void discard_input() override;
  const std::string& device() const { return device_; }

 private:
  std::string device_;
  int fd_ = -1;
};

}  // namespace rgbdt::tilt_lidar
