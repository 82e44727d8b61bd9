#include "rgbdt/tilt_lidar/serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "rgbdt/core/error.hpp"

namespace rgbdt::tilt_lidar {

namespace {

speed_t to_speed(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return 0;
  }
}

}  // namespace

SerialPort::SerialPort(const std::string& device, int baud) : device_(device) {
  const speed_t speed = to_speed(baud);
  if (speed == 0) throw core::Error(device, "unsupported baud rate " + std::to_string(baud));
  fd_ = ::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) throw core::Error(device, std::string("cannot open serial port: ") + std::strerror(errno));
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd_);
    throw core::Error(device, "not a serial port (tcgetattr: " + why + ")");
  }
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd_);
    throw core::Error(device, "cannot configure serial port: " + why);
  }
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);
}

void SerialPort::write(const std::uint8_t* data, std::size_t size) {
  std::size_t off = 0;
  while (off < size) {
    const ssize_t n = ::write(fd_, data + off, size - off);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) {
      pollfd p{fd_, POLLOUT, 0};
      ::poll(&p, 1, 10);
      continue;
    }
    if (n < 0) throw core::Error(device_, std::string("write failed: ") + std::strerror(errno));
    off += static_cast<std::size_t>(n);
  }
}

std::size_t SerialPort::read(std::uint8_t* data, std::size_t size, int timeout_ms) {
  pollfd p{fd_, POLLIN, 0};
  const int rc = ::poll(&p, 1, timeout_ms);
  if (rc <= 0) return 0;
  const ssize_t n = ::read(fd_, data, size);
  if (n < 0 && (errno == EAGAIN || errno == EINTR)) return 0;
  if (n < 0) throw core::Error(device_, std::string("read failed: ") + std::strerror(errno));
  return static_cast<std::size_t>(n);
}

void SerialPort::discard_input() { ::tcflush(fd_, TCIFLUSH); }

}  // namespace rgbdt::tilt_lidar
