#include "rgbdt/tilt_lidar/dynamixel.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::tilt_lidar::dxl {

namespace {

constexpr std::uint8_t kHeader[4] = {0xFF, 0xFF, 0xFD, 0x00};

std::string hex(unsigned v) {
  std::ostringstream os;
  os << "0x" << std::hex << v;
  return os.str();
}

const char* error_name(int e) {
  switch (e) {
    case 1: return "result fail";
    case 2: return "instruction error";
    case 3: return "CRC error";
    case 4: return "data range error";
    case 5: return "data length error";
    case 6: return "data limit error";
    case 7: return "access error";
    default: return "unknown error";
  }
}

}  // namespace

std::uint16_t crc16(const std::uint8_t* data, std::size_t size, std::uint16_t crc) {
  // Bitwise CRC-16 with polynomial 0x8005 (the packets are short; no table needed).
  for (std::size_t k = 0; k < size; ++k) {
    crc ^= static_cast<std::uint16_t>(data[k]) << 8;
    for (int b = 0; b < 8; ++b) crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x8005) : static_cast<std::uint16_t>(crc << 1);
  }
  return crc;
}

std::vector<std::uint8_t> encode(const Packet& p) {
  std::vector<std::uint8_t> body{p.instruction};
  if (p.instruction == kStatus) body.push_back(p.error);
  body.insert(body.end(), p.params.begin(), p.params.end());
  // Byte stuffing: after every FF FF FD inside INST+PARAMS insert FD.
  std::vector<std::uint8_t> stuffed;
  stuffed.reserve(body.size() + 4);
  for (const std::uint8_t b : body) {
    stuffed.push_back(b);
    const std::size_t n = stuffed.size();
    if (n >= 3 && stuffed[n - 3] == 0xFF && stuffed[n - 2] == 0xFF && stuffed[n - 1] == 0xFD) stuffed.push_back(0xFD);
  }
  const std::size_t len = stuffed.size() + 2;
  if (len > 0xFFFF) throw std::invalid_argument("dxl::encode: packet of " + std::to_string(len) + " bytes is too long");
  std::vector<std::uint8_t> out(kHeader, kHeader + 4);
  out.push_back(p.id);
  out.push_back(static_cast<std::uint8_t>(len & 0xFF));
  out.push_back(static_cast<std::uint8_t>(len >> 8));
  out.insert(out.end(), stuffed.begin(), stuffed.end());
  const std::uint16_t crc = crc16(out.data(), out.size());
  out.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  out.push_back(static_cast<std::uint8_t>(crc >> 8));
  return out;
}

void PacketParser::feed(const std::uint8_t* data, std::size_t size) { buffer_.insert(buffer_.end(), data, data + size); }

std::optional<Packet> PacketParser::next() {
  for (;;) {
    auto it = std::search(buffer_.begin(), buffer_.end(), kHeader, kHeader + 4);
    if (it == buffer_.end()) {
      // Keep a possible partial header at the end.
      const std::size_t keep = std::min<std::size_t>(buffer_.size(), 3);
      buffer_.erase(buffer_.begin(), buffer_.end() - static_cast<std::ptrdiff_t>(keep));
      return std::nullopt;
    }
    buffer_.erase(buffer_.begin(), it);
    if (buffer_.size() < 7) return std::nullopt;
    const std::size_t len = buffer_[5] | (static_cast<std::size_t>(buffer_[6]) << 8);
    if (len < 3 || len > kMaxLength) {
      ++framing_errors_;
      buffer_.erase(buffer_.begin());
      continue;
    }
    const std::size_t total = 7 + len;
    if (buffer_.size() < total) return std::nullopt;
    const std::uint16_t crc = crc16(buffer_.data(), total - 2);
    const std::uint16_t got = static_cast<std::uint16_t>(buffer_[total - 2] | (buffer_[total - 1] << 8));
    if (crc != got) {
      ++crc_errors_;
      buffer_.erase(buffer_.begin());
      continue;
    }
    // Unstuff INST+PARAMS.
    std::vector<std::uint8_t> body;
    body.reserve(len - 2);
    for (std::size_t k = 7; k < total - 2; ++k) {
      const std::size_t n = body.size();
      if (buffer_[k] == 0xFD && n >= 3 && body[n - 3] == 0xFF && body[n - 2] == 0xFF && body[n - 1] == 0xFD) continue;
      body.push_back(buffer_[k]);
    }
    Packet p;
    p.id = buffer_[4];
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(total));
    p.instruction = body[0];
    std::size_t first = 1;
    if (p.instruction == kStatus) {
      if (body.size() < 2) {
        ++framing_errors_;
        continue;
      }
      p.error = body[1];
      first = 2;
    }
    p.params.assign(body.begin() + static_cast<std::ptrdiff_t>(first), body.end());
    return p;
  }
}

std::vector<std::uint8_t> le_bytes(std::int64_t value, int size) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(size));
  for (int k = 0; k < size; ++k) out[static_cast<std::size_t>(k)] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(value) >> (8 * k)) & 0xFF);
  return out;
}

std::int64_t from_le(const std::uint8_t* data, int size, bool is_signed) {
  std::uint64_t v = 0;
  for (int k = size - 1; k >= 0; --k) v = (v << 8) | data[k];
  if (is_signed && size < 8 && (v >> (8 * size - 1)) & 1) v |= ~0ULL << (8 * size);
  return static_cast<std::int64_t>(v);
}

std::string BusOptions::validate() const {
  if (timeout_ms <= 0) return "timeout_ms " + std::to_string(timeout_ms) + " must be positive";
  if (retries < 0) return "retries " + std::to_string(retries) + " must be >= 0";
  return {};
}

DynamixelBus::DynamixelBus(ByteTransport& transport, const BusOptions& options)
    : transport_(transport), options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("DynamixelBus: " + why);
}

std::optional<Packet> DynamixelBus::receive_from(std::uint8_t id, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  std::uint8_t buf[256];
  for (;;) {
    const std::int64_t crc_before = parser_.crc_errors();
    while (auto p = parser_.next()) {
      if (p->instruction == kStatus && p->id == id) {
        stats_.crc_errors += parser_.crc_errors() - crc_before;
        return p;
      }
      // Echo of our own instruction (half-duplex adapters) or another motor: ignored.
    }
    stats_.crc_errors += parser_.crc_errors() - crc_before;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0) return std::nullopt;
    const std::size_t n = transport_.read(buf, sizeof buf, static_cast<int>(left));
    if (n > 0) parser_.feed(buf, n);
  }
}

Packet DynamixelBus::transact(const Packet& request, const char* what) {
  const auto bytes = encode(request);
  ++stats_.requests;
  for (int attempt = 0; attempt <= options_.retries; ++attempt) {
    if (attempt > 0) ++stats_.retries;
    parser_.clear();
    transport_.discard_input();
    transport_.write(bytes.data(), bytes.size());
    auto reply = receive_from(request.id, options_.timeout_ms);
    if (!reply) {
      ++stats_.timeouts;
      continue;
    }
    const int err = reply->error & 0x7F;
    if (err != 0) {
      ++stats_.failures;
      throw core::Error("dynamixel id " + std::to_string(request.id),
                        std::string(what) + " rejected by the motor: " + error_name(err) + " (" + hex(reply->error) + ")");
    }
    if (reply->error & 0x80) core::log_warning("dynamixel id ", int(request.id), ": hardware alert bit set");
    return *reply;
  }
  ++stats_.failures;
  throw core::Error("dynamixel id " + std::to_string(request.id),
                    std::string(what) + ": no valid reply after " + std::to_string(options_.retries + 1) +
                        " attempts of " + std::to_string(options_.timeout_ms) + " ms (timeout or corrupt CRC)");
}

DynamixelBus::PingReply DynamixelBus::ping(std::uint8_t id) {
  const Packet r = transact({id, kPing, 0, {}}, "ping");
  if (r.params.size() < 3) throw core::Error("dynamixel id " + std::to_string(id), "ping reply has " + std::to_string(r.params.size()) + " parameter bytes, expected 3");
  return {static_cast<std::uint16_t>(r.params[0] | (r.params[1] << 8)), r.params[2]};
}

std::vector<std::uint8_t> DynamixelBus::read(std::uint8_t id, std::uint16_t address, std::uint16_t length) {
  Packet req{id, kRead, 0, {}};
  const auto a = le_bytes(address, 2), l = le_bytes(length, 2);
  req.params = {a[0], a[1], l[0], l[1]};
  const Packet r = transact(req, "read");
  if (r.params.size() != length) {
    throw core::Error("dynamixel id " + std::to_string(id), "read of " + std::to_string(length) + " bytes at " +
                                                                std::to_string(address) + " returned " + std::to_string(r.params.size()));
  }
  return r.params;
}

void DynamixelBus::write(std::uint8_t id, std::uint16_t address, const std::vector<std::uint8_t>& data) {
  Packet req{id, kWrite, 0, le_bytes(address, 2)};
  req.params.insert(req.params.end(), data.begin(), data.end());
  transact(req, "write");
}

std::vector<std::vector<std::uint8_t>> DynamixelBus::sync_read(const std::vector<std::uint8_t>& ids, std::uint16_t address,
                                                               std::uint16_t length) {
  Packet req{kBroadcastId, kSyncRead, 0, {}};
  const auto a = le_bytes(address, 2), l = le_bytes(length, 2);
  req.params = {a[0], a[1], l[0], l[1]};
  req.params.insert(req.params.end(), ids.begin(), ids.end());
  const auto bytes = encode(req);
  ++stats_.requests;
  for (int attempt = 0; attempt <= options_.retries; ++attempt) {
    if (attempt > 0) ++stats_.retries;
    parser_.clear();
    transport_.discard_input();
    transport_.write(bytes.data(), bytes.size());
    std::vector<std::vector<std::uint8_t>> out;
    for (const std::uint8_t id : ids) {
      auto reply = receive_from(id, options_.timeout_ms);
      if (!reply || (reply->error & 0x7F) || reply->params.size() != length) break;
      out.push_back(reply->params);
    }
    if (out.size() == ids.size()) return out;
    ++stats_.timeouts;
  }
  ++stats_.failures;
  throw core::Error("dynamixel sync read", "not every motor of " + std::to_string(ids.size()) + " answered after " +
                                               std::to_string(options_.retries + 1) + " attempts");
}

std::string SweepOptions::validate() const {
  std::ostringstream os;
  if (!(upper_rad > lower_rad)) os << "sweep limits [" << lower_rad << ", " << upper_rad << "] rad are not increasing";
  else if (!(speed_rad_s > 0)) os << "speed_rad_s " << speed_rad_s << " must be positive";
  else if (!(turn_tolerance_rad > 0)) os << "turn_tolerance_rad must be positive";
  else if (!(table.counts_per_revolution > 0) || !(table.rpm_per_velocity_unit > 0)) os << "control table resolution must be positive";
  return os.str();
}

SweepController::SweepController(DynamixelBus& bus, const SweepOptions& options, Clock clock)
    : bus_(bus), options_(options), clock_(std::move(clock)) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("SweepController: " + why);
  if (!clock_) throw std::invalid_argument("SweepController: empty clock");
}

double SweepController::angle_from_count(std::int64_t count) const {
  return static_cast<double>(count) * 2.0 * M_PI / options_.table.counts_per_revolution;
}

std::int64_t SweepController::count_from_angle(double angle_rad) const {
  return std::llround(angle_rad * options_.table.counts_per_revolution / (2.0 * M_PI));
}

void SweepController::send_goal(double angle_rad) {
  bus_.write(options_.id, options_.table.goal_position, le_bytes(count_from_angle(angle_rad), 4));
}

void SweepController::start() {
  const auto& t = options_.table;
  bus_.write(options_.id, t.torque_enable, {1});
  const double rpm = options_.speed_rad_s * 60.0 / (2.0 * M_PI);
  const auto units = std::max<std::int64_t>(1, std::llround(rpm / t.rpm_per_velocity_unit));
  bus_.write(options_.id, t.goal_velocity, le_bytes(units, 4));
  direction_ = 1;
  send_goal(options_.upper_rad);
}

std::optional<SweepController::Reading> SweepController::step() {
  const double t0 = clock_();
  std::vector<std::uint8_t> data;
  try {
    data = bus_.read(options_.id, options_.table.present_position, 4);
  } catch (const core::Error& e) {
    core::log_debug(e.what());
    return std::nullopt;
  }
  const double t1 = clock_();
  Reading r;
  r.count = from_le(data.data(), 4, true);
  // The motor samples its encoder while answering: the midpoint of the exchange is the
  // best stamp without a motor-side clock (error <= half the round trip).
  r.sample.time_s = 0.5 * (t0 + t1);
  r.sample.angle_rad = angle_from_count(r.count);
  const double a = r.sample.angle_rad;
  try {
    if (direction_ > 0 && a >= options_.upper_rad - options_.turn_tolerance_rad) {
      direction_ = -1;
      send_goal(options_.lower_rad);
    } else if (direction_ < 0 && a <= options_.lower_rad + options_.turn_tolerance_rad) {
      direction_ = 1;
      send_goal(options_.upper_rad);
    }
  } catch (const core::Error& e) {
    // The reading is still valid; the turn is retried at the next step.
    direction_ = -direction_;
    core::log_warning(e.what());
  }
  return r;
}

void SweepController::stop() {
  try {
    bus_.write(options_.id, options_.table.torque_enable, {0});
  } catch (const core::Error& e) {
    core::log_warning("dynamixel: torque off failed: ", e.what());
  }
}

}  // namespace rgbdt::tilt_lidar::dxl
