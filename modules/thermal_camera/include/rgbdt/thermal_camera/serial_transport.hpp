#pragma once
/// \file
/// Byte transports for serial-controlled cores (the Tau2's command channel). The protocol
/// code only sees SerialTransport, so it runs the same over a tty, over libusb, or against
/// an emulator on a pseudo-terminal.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace rgbdt::thermal_camera {

class SerialTransport {
 public:
  virtual ~SerialTransport() = default;
  /// Writes all bytes or throws rgbdt::core::Error naming the device.
  virtual void write(const uint8_t* data, size_t size) = 0;
  /// Reads up to `size` bytes, waiting at most `timeout_ms` for the first one. Returns the
  /// number read; 0 means the timeout passed. Throws rgbdt::core::Error on I/O failure.
  virtual size_t read(uint8_t* data, size_t size, int timeout_ms) = 0;
  /// Discards bytes received but not yet read.
  virtual void flush_input() = 0;
  /// The device, e.g. "/dev/ttyUSB0" or "usb 0403:6015".
  virtual std::string name() const = 0;
};

/// A POSIX tty (USB-serial adapter through its kernel driver, a pseudo-terminal, a UART):
/// raw mode, 8N1, no flow control.
class TermiosTransport : public SerialTransport {
 public:
  /// Throws rgbdt::core::Error naming the path if it cannot be opened or configured, and
  /// std::invalid_argument for a baud rate termios does not define. The Tau2 ships at
  /// 57600 baud (921600 selectable).
  explicit TermiosTransport(const std::string& path, int baud = 57600);
  ~TermiosTransport() override;
  TermiosTransport(const TermiosTransport&) = delete;
  TermiosTransport& operator=(const TermiosTransport&) = delete;

  void write(const uint8_t* data, size_t size) override;
  size_t read(uint8_t* data, size_t size, int timeout_ms) override;
  void flush_input() override;
  std::string name() const override { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// Options of the libusb transport for FTDI USB-serial bridges (FT232R/FT232H/FT2232
/// style: vendor control requests for line settings, bulk endpoints, two modem-status
/// bytes at the start of every IN packet), as on the Tau2 USB/VPC accessory boards.
struct FtdiUsbOptions {
  uint16_t vendor_id = 0x0403;   ///< FTDI
  uint16_t product_id = 0x6015;  ///< FT-X series; 0x6001 FT232R, 0x6010 FT2232, 0x6014 FT232H
  std::string serial;            ///< USB serial string to pick one of several; empty: first
  int interface_number = 0;      ///< channel A = 0
  int baud = 57600;              ///< Tau2 default
  int latency_timer_ms = 2;      ///< FTDI holds IN data up to this long; small = responsive
  std::string validate() const;
};

/// Drives an FTDI USB-serial bridge directly through libusb (no ftdi_sio kernel driver
/// needed; it is detached while the transport is open). Written against the FTDI
/// protocol facts in its comments and compiled here; it needs a device to be tested.
class FtdiUsbTransport : public SerialTransport {
 public:
  /// Throws rgbdt::core::Error naming vendor:product (and serial) when no such device is
  /// found, it cannot be claimed (permissions: see the udev note in the module README),
  /// or a line setting is refused.
  explicit FtdiUsbTransport(const FtdiUsbOptions& options = {});
  ~FtdiUsbTransport() override;
  FtdiUsbTransport(const FtdiUsbTransport&) = delete;
  FtdiUsbTransport& operator=(const FtdiUsbTransport&) = delete;

  void write(const uint8_t* data, size_t size) override;
  size_t read(uint8_t* data, size_t size, int timeout_ms) override;
  void flush_input() override;
  std::string name() const override;

  /// FTDI baud-rate divisor for a 3 MHz base clock (FT232R/FT-X): returns the (value,
  /// index) pair of the SET_BAUD_RATE request and the rate actually obtained.
  struct BaudDivisor {
    uint16_t value = 0;
    uint16_t index = 0;
    double actual_baud = 0.0;
  };
  static BaudDivisor baud_divisor(int baud);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rgbdt::thermal_camera
