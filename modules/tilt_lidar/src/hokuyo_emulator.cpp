#include "rgbdt/tilt_lidar/hokuyo_emulator.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <random>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::tilt_lidar {

namespace {

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool send_all(int fd, const std::string& bytes) {
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    off += static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

std::string ScipDevice::handle(const std::string& line) {
  scip::Response r;
  r.echo = line;
  r.status = "00";
  if (line == "SCIP2.0" || line.rfind("SS", 0) == 0 || line.rfind("CR", 0) == 0 || line.rfind("HS", 0) == 0 ||
      line.rfind("TM", 0) == 0) {
    // Protocol switch, baud rate, motor speed, high sensitivity, time mode: accepted.
  } else if (line == "BM") {
    if (laser_on_) r.status = "02";  // already on
    laser_on_ = true;
  } else if (line == "QT") {
    laser_on_ = false;
    streaming_ = false;
  } else if (line == "RS" || line == "RT") {
    laser_on_ = false;
    streaming_ = false;
  } else if (line == "VV") {
    r.lines = {"VEND:Hokuyo Automatic Co.,Ltd.;", "PROD:SOKUIKI Sensor " + spec_.model + ";",
               "FIRM:1.20.00(rgbdt emulator);", "PROT:SCIP 2.0;", "SERI:" + spec_.serial + ";"};
  } else if (line == "PP") {
    r.lines = {"MODL:" + spec_.model + "(Hokuyo Automatic Co.,Ltd.);",
               "DMIN:" + std::to_string(spec_.range_min_mm) + ";",
               "DMAX:" + std::to_string(spec_.range_max_mm) + ";",
               "ARES:" + std::to_string(spec_.steps_per_revolution) + ";",
               "AMIN:" + std::to_string(spec_.first_step) + ";",
               "AMAX:" + std::to_string(spec_.last_step) + ";",
               "AFRT:" + std::to_string(spec_.front_step) + ";",
               "SCAN:" + std::to_string(spec_.motor_rpm) + ";"};
  } else if (line == "II") {
    r.lines = {"MODL:" + spec_.model + ";", std::string("LASR:") + (laser_on_ ? "ON" : "OFF") + ";",
               "SCSP:" + std::to_string(spec_.motor_rpm) + ";", "MESM:Measuring by Sensitive Mode;",
               "SBPS:Ethernet 100 [Mbps];", "TIME:000000;", "STAT:Sensor works well.;"};
  } else if (const auto cmd = scip::parse_measurement_command(line)) {
    if (cmd->start_step < spec_.first_step || cmd->end_step > spec_.last_step) {
      r.status = "04";  // end/start step out of range
    } else {
      command_ = *cmd;
      command_line_ = line;
      scans_left_ = cmd->scans;
      streaming_ = true;
      laser_on_ = true;
    }
  } else {
    r.status = "0E";  // undefined command
  }
  return scip::encode_response(r);
}

std::string ScipDevice::scan_message(const scip::ScanFrame& frame) {
  scip::Response r;
  r.echo = command_line_;
  if (command_.scans > 0) {
    --scans_left_;
    // The echo carries the number of scans still to come.
    const int left = std::max(scans_left_, 0);
    r.echo = command_line_.substr(0, 13) + (left < 10 ? "0" : "") + std::to_string(left);
    if (scans_left_ <= 0) streaming_ = false;
  }
  r.status = "99";
  r.lines = scip::encode_scan_lines(frame);
  return scip::encode_response(r);
}

std::string HokuyoEmulatorOptions::validate() const {
  std::ostringstream os;
  if (port < 0 || port > 65535) os << "port " << port << " must be in 0..65535";
  else if (!(scan_period_s > 0)) os << "scan_period_s " << scan_period_s << " must be positive";
  else if (device.last_step < device.first_step) os << "device steps [" << device.first_step << ", " << device.last_step << "] are empty";
  return os.str();
}

HokuyoEmulator::HokuyoEmulator(RangeSource source, HokuyoEmulatorOptions options)
    : source_(std::move(source)), options_(std::move(options)), port_(options_.port) {
  if (const std::string why = options_.validate(); !why.empty()) throw std::invalid_argument("HokuyoEmulator: " + why);
  if (!source_) throw std::invalid_argument("HokuyoEmulator: empty range source");
}

HokuyoEmulator::~HokuyoEmulator() { stop(); }

void HokuyoEmulator::start() {
  if (running_) return;
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) throw core::Error("hokuyo emulator", std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bool bound = false;
  if (port_ == 0) {
    // Not an ephemeral port (Linux: 32768-60999): while the emulator is stopped, a client
    // retrying connect() to an ephemeral port can be given that same port as its source
    // and connect to itself (TCP simultaneous open), then block writing to itself.
    std::mt19937 rng(static_cast<unsigned>(::getpid()) ^ static_cast<unsigned>(reinterpret_cast<std::uintptr_t>(this)));
    for (int attempt = 0; attempt < 200 && !bound; ++attempt) {
      const int candidate = 20000 + static_cast<int>(rng() % 12000);
      addr.sin_port = htons(static_cast<std::uint16_t>(candidate));
      bound = ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    }
  } else {
    addr.sin_port = htons(static_cast<std::uint16_t>(port_));
    bound = ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  if (!bound || ::listen(listen_fd_, 1) != 0) {
    const std::string why = std::strerror(errno);
    ::close(listen_fd_);
    listen_fd_ = -1;
    throw core::Error("hokuyo emulator 127.0.0.1:" + std::to_string(port_), "cannot listen: " + why);
  }
  socklen_t len = sizeof addr;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  if (t0_ == 0.0) t0_ = steady_now_s();
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void HokuyoEmulator::stop() {
  if (!running_) return;
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
}

std::deque<HokuyoEmulator::Served> HokuyoEmulator::served() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return served_;
}

void HokuyoEmulator::run() {
  while (running_) {
    pollfd p{listen_fd_, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0) continue;
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ++connections_;
    serve_client(fd);
    ::close(fd);
  }
}

void HokuyoEmulator::serve_client(int fd) {
  ScipDevice device(options_.device);
  std::string pending;
  double next_scan_s = steady_now_s();
  while (running_) {
    const double now = steady_now_s();
    int wait_ms = 20;
    if (device.streaming()) wait_ms = std::max(0, static_cast<int>(std::ceil((next_scan_s - now) * 1e3)));
    pollfd p{fd, POLLIN, 0};
    const int rc = ::poll(&p, 1, std::min(wait_ms, 20));
    if (rc > 0) {
      char buf[512];
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) return;  // client closed
      pending.append(buf, static_cast<std::size_t>(n));
      std::size_t lf;
      while ((lf = pending.find_first_of("\n\r")) != std::string::npos) {
        std::string line = pending.substr(0, lf);
        pending.erase(0, lf + 1);
        if (line.empty()) continue;
        const bool was_streaming = device.streaming();
        if (!send_all(fd, device.handle(line))) return;
        if (device.streaming() && !was_streaming) next_scan_s = steady_now_s();
      }
      if (pending.size() > 1024) pending.clear();  // garbage without LF
    }
    if (device.streaming() && steady_now_s() >= next_scan_s) {
      const std::int64_t index = next_index_++;
      const double t = next_scan_s - t0_;
      scip::ScanFrame frame = source_(index, t);
      frame.timestamp_ms = static_cast<std::uint32_t>(std::llround(t * 1e3)) & 0xFFFFFF;
      frame.ranges_mm.resize(static_cast<std::size_t>(device.measurement_beams()), 0);
      if (device.measurement_intensity()) frame.intensity.resize(frame.ranges_mm.size(), 0);
      else frame.intensity.clear();
      const std::string message = device.scan_message(frame);
      {  // remembered before sending: a fast client may look it up as soon as it arrives
        std::lock_guard<std::mutex> lock(mutex_);
        served_.push_back({index, std::move(frame)});
        while (served_.size() > options_.keep_served) served_.pop_front();
      }
      if (!send_all(fd, message)) return;
      ++scans_sent_;
      next_scan_s += options_.scan_period_s;
      // After a stall, skip missed slots rather than bursting (a real scanner cannot).
      if (steady_now_s() - next_scan_s > options_.scan_period_s) next_scan_s = steady_now_s();
    }
  }
}

}  // namespace rgbdt::tilt_lidar
