#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/thermal_camera/serial_transport.hpp"

namespace rgbdt::thermal_camera {
namespace {

speed_t speed_for(int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 921600:
      return B921600;
    default:
      throw std::invalid_argument(
          "baud = " + std::to_string(baud) +
          ", expected 9600, 19200, 38400, 57600, 115200, 230400, 460800 or 921600");
  }
}

std::string errno_text() { return std::strerror(errno); }

}  // namespace

TermiosTransport::TermiosTransport(const std::string& path, int baud) : path_(path) {
  const speed_t speed = speed_for(baud);
  fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC | O_NONBLOCK);
  if (fd_ < 0) throw core::Error(path, "cannot open serial port: " + errno_text());
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const std::string why = errno_text();
    ::close(fd_);
    throw core::Error(path, "not a serial port (tcgetattr: " + why + ")");
  }
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~(CSTOPB | CRTSCTS | PARENB);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const std::string why = errno_text();
    ::close(fd_);
    throw core::Error(path, "cannot set " + std::to_string(baud) + " baud 8N1 raw: " + why);
  }
  ::tcflush(fd_, TCIOFLUSH);
}

TermiosTransport::~TermiosTransport() {
  if (fd_ >= 0) ::close(fd_);
}

void TermiosTransport::write(const uint8_t* data, size_t size) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd_, data + done, size - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd_, POLLOUT, 0};
      if (::poll(&p, 1, 1000) <= 0) throw core::Error(path_, "write timed out");
      continue;
    }
    throw core::Error(path_, "write failed: " + errno_text());
  }
}

size_t TermiosTransport::read(uint8_t* data, size_t size, int timeout_ms) {
  pollfd p{fd_, POLLIN, 0};
  int rc;
  do {
    rc = ::poll(&p, 1, timeout_ms);
  } while (rc < 0 && errno == EINTR);
  if (rc < 0) throw core::Error(path_, "poll failed: " + errno_text());
  if (rc == 0) return 0;
  const ssize_t n = ::read(fd_, data, size);
  if (n > 0) return static_cast<size_t>(n);
  if (n < 0 && (errno == EAGAIN || errno == EINTR)) return 0;
  if (p.revents & (POLLHUP | POLLERR)) throw core::Error(path_, "device closed or unplugged");
  if (n < 0) throw core::Error(path_, "read failed: " + errno_text());
  return 0;
}

void TermiosTransport::flush_input() { ::tcflush(fd_, TCIFLUSH); }

}  // namespace rgbdt::thermal_camera
