#include "rgbdt/tilt_lidar/dynamixel_emulator.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>

#include "rgbdt/core/error.hpp"

namespace rgbdt::tilt_lidar::dxl {

namespace {

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

constexpr std::size_t kMemory = 1024;

}  // namespace

EmulatedMotor::EmulatedMotor(const EmulatedMotorOptions& options)
    : options_(options), memory_(kMemory, 0), rng_state_(options.seed ? options.seed : 1) {
  char name[256] = {};
  if (::openpty(&master_fd_, &slave_fd_, name, nullptr, nullptr) != 0) {
    throw core::Error("dynamixel emulator", std::string("openpty failed: ") + std::strerror(errno));
  }
  termios tio{};
  ::tcgetattr(slave_fd_, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(slave_fd_, TCSANOW, &tio);
  ::fcntl(master_fd_, F_SETFD, FD_CLOEXEC);
  ::fcntl(slave_fd_, F_SETFD, FD_CLOEXEC);
  device_ = name;
  pos_rad_ = options_.initial_angle_rad;
  last_s_ = now_s();
  const auto& t = options_.table;
  auto put = [this](std::uint16_t addr, std::int64_t v, int size) {
    const auto b = le_bytes(v, size);
    std::copy(b.begin(), b.end(), memory_.begin() + addr);
  };
  put(0, options_.model, 2);
  put(6, options_.firmware, 1);
  put(7, options_.id, 1);
  put(t.goal_position, position_count(), 4);
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

EmulatedMotor::~EmulatedMotor() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  ::close(master_fd_);
  ::close(slave_fd_);
}

std::int64_t EmulatedMotor::position_count() const {
  return std::llround(pos_rad_ * options_.table.counts_per_revolution / (2.0 * M_PI));
}

double EmulatedMotor::angle_rad() {
  std::lock_guard<std::mutex> lock(mutex_);
  advance(now_s());
  return pos_rad_;
}

double EmulatedMotor::velocity_rad_s() {
  std::lock_guard<std::mutex> lock(mutex_);
  advance(now_s());
  return vel_rad_s_;
}

void EmulatedMotor::advance(double t) {
  const auto& tab = options_.table;
  const bool torque = memory_[tab.torque_enable] != 0;
  const double goal = from_le(&memory_[tab.goal_position], 4, true) * 2.0 * M_PI / tab.counts_per_revolution;
  const std::int64_t vunits = std::llabs(from_le(&memory_[tab.goal_velocity], 4, true));
  const double vmax = vunits == 0 ? options_.max_speed_rad_s
                                  : std::min(options_.max_speed_rad_s, vunits * tab.rpm_per_velocity_unit * 2.0 * M_PI / 60.0);
  const double a = options_.acceleration_rad_s2;
  // Integrate in 0.5 ms steps: trapezoidal profile towards the goal.
  while (last_s_ < t) {
    const double dt = std::min(5e-4, t - last_s_);
    double want = 0.0;
    if (torque) {
      const double d = goal - pos_rad_;
      want = std::copysign(std::min(vmax, std::sqrt(2.0 * a * std::abs(d))), d);
    }
    const double dv = std::clamp(want - vel_rad_s_, -a * dt, a * dt);
    vel_rad_s_ += dv;
    pos_rad_ += vel_rad_s_ * dt;
    last_s_ += dt;
  }
  const auto b = le_bytes(position_count(), 4);
  std::copy(b.begin(), b.end(), memory_.begin() + tab.present_position);
  const auto v = le_bytes(std::llround(vel_rad_s_ * 60.0 / (2.0 * M_PI) / tab.rpm_per_velocity_unit), 4);
  std::copy(v.begin(), v.end(), memory_.begin() + tab.present_velocity);
}

void EmulatedMotor::reply(const Packet& status) {
  rng_state_ = rng_state_ * 1103515245u + 12345u;
  const double u = ((rng_state_ >> 8) & 0xFFFF) / 65536.0;
  if (u < drop_probability_) return;
  auto bytes = encode(status);
  rng_state_ = rng_state_ * 1103515245u + 12345u;
  const double v = ((rng_state_ >> 8) & 0xFFFF) / 65536.0;
  if (v < corrupt_probability_) bytes.back() ^= 0x5A;
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::write(master_fd_, bytes.data() + off, bytes.size() - off);
    if (n <= 0) return;
    off += static_cast<std::size_t>(n);
  }
}

void EmulatedMotor::handle(const Packet& p) {
  ++requests_;
  if (silent_) return;
  const std::uint8_t id = options_.id;
  Packet status{id, kStatus, 0, {}};
  std::lock_guard<std::mutex> lock(mutex_);
  advance(now_s());
  if (p.instruction == kSyncRead && p.id == kBroadcastId) {
    if (p.params.size() < 5) return;
    const std::uint16_t addr = static_cast<std::uint16_t>(p.params[0] | (p.params[1] << 8));
    const std::uint16_t len = static_cast<std::uint16_t>(p.params[2] | (p.params[3] << 8));
    if (std::find(p.params.begin() + 4, p.params.end(), id) == p.params.end()) return;
    if (addr + len > kMemory) status.error = 7;
    else status.params.assign(memory_.begin() + addr, memory_.begin() + addr + len);
    reply(status);
    return;
  }
  if (p.id != id) return;  // another motor or broadcast write: no reply
  switch (p.instruction) {
    case kPing:
      status.params = {static_cast<std::uint8_t>(options_.model & 0xFF), static_cast<std::uint8_t>(options_.model >> 8),
                       options_.firmware};
      break;
    case kRead: {
      if (p.params.size() != 4) { status.error = 5; break; }
      const std::size_t addr = p.params[0] | (p.params[1] << 8), len = p.params[2] | (p.params[3] << 8);
      if (addr + len > kMemory) { status.error = 7; break; }
      status.params.assign(memory_.begin() + static_cast<std::ptrdiff_t>(addr),
                           memory_.begin() + static_cast<std::ptrdiff_t>(addr + len));
      break;
    }
    case kWrite: {
      if (p.params.size() < 3) { status.error = 5; break; }
      const std::size_t addr = p.params[0] | (p.params[1] << 8), len = p.params.size() - 2;
      if (addr + len > kMemory) { status.error = 7; break; }
      std::copy(p.params.begin() + 2, p.params.end(), memory_.begin() + static_cast<std::ptrdiff_t>(addr));
      break;
    }
    default:
      status.error = 2;  // instruction error
  }
  reply(status);
}

void EmulatedMotor::run() {
  PacketParser parser;
  std::uint8_t buf[512];
  while (running_) {
    pollfd p{master_fd_, POLLIN, 0};
    if (::poll(&p, 1, 10) <= 0) continue;
    const ssize_t n = ::read(master_fd_, buf, sizeof buf);
    if (n <= 0) continue;
    parser.feed(buf, static_cast<std::size_t>(n));
    const std::int64_t crc_before = parser.crc_errors();
    while (auto packet = parser.next()) {
      if (packet->instruction == kStatus) continue;
      handle(*packet);
    }
    crc_errors_seen_ += parser.crc_errors() - crc_before;
  }
}

}  // namespace rgbdt::tilt_lidar::dxl
