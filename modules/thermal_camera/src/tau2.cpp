#include "rgbdt/thermal_camera/tau2.hpp"

#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace rgbdt::thermal_camera {

using tau2::Function;
using tau2::Packet;
using tau2::ParseResult;
using tau2::Status;

double kelvin_per_count(Tau2TLinearResolution resolution) {
  return resolution == Tau2TLinearResolution::kHigh ? 0.04 : 0.4;
}

std::string Tau2Options::validate() const {
  if (reply_timeout_ms < 1)
    return "reply_timeout_ms = " + std::to_string(reply_timeout_ms) + ", expected >= 1";
  if (busy_retries < 0) return "busy_retries = " + std::to_string(busy_retries) + ", expected >= 0";
  return {};
}

Tau2::Tau2(std::unique_ptr<SerialTransport> transport, const Tau2Options& options)
    : transport_(std::move(transport)), options_(options) {
  if (!transport_) throw std::invalid_argument("Tau2: null transport");
  if (const auto why = options.validate(); !why.empty()) {
    throw std::invalid_argument("Tau2Options: " + why);
  }
}

Packet Tau2::transact(Function function, const std::vector<uint8_t>& payload) {
  using Clock = std::chrono::steady_clock;
  const auto code = static_cast<uint8_t>(function);
  const std::string what = tau2::function_name(code);
  const std::string source = "Tau2 on " + transport_->name();
  const std::vector<uint8_t> command = tau2::encode({0, code, payload});
  for (int attempt = 0;; ++attempt) {
    transport_->flush_input();
    transport_->write(command.data(), command.size());

    std::vector<uint8_t> rx;
    const auto deadline = Clock::now() + std::chrono::milliseconds(options_.reply_timeout_ms);
    ParseResult r;
    while (true) {
      r = tau2::parse(rx.data(), rx.size());
      if (r.kind == ParseResult::Kind::kPacket) break;
      if (r.kind == ParseResult::Kind::kError) {
        throw tau2::ProtocolError(source, "corrupt reply to " + what + ": " + r.error);
      }
      const auto left_ms =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      size_t got = 0;
      if (left_ms > 0) {
        uint8_t buf[256];
        const size_t want = std::min(sizeof buf, r.needed - rx.size());
        got = transport_->read(buf, want, static_cast<int>(left_ms));
        rx.insert(rx.end(), buf, buf + got);
      }
      if (got == 0 && Clock::now() >= deadline) {
        if (rx.empty()) {
          throw Tau2Error(source,
                          "no reply to " + what + " within " +
                              std::to_string(options_.reply_timeout_ms) + " ms",
                          Status::kTimeoutError);
        }
        throw tau2::ProtocolError(source, "truncated reply to " + what + ": " +
                                              std::to_string(rx.size()) + " bytes, expected " +
                                              std::to_string(r.needed));
      }
    }
    const Packet& reply = r.packet;
    if (reply.function != code) {
      throw Tau2Error(
          source, "reply to " + tau2::function_name(reply.function) + " for a " + what + " command",
          static_cast<Status>(reply.status));
    }
    const auto status = static_cast<Status>(reply.status);
    if (status == Status::kBusy && attempt < options_.busy_retries) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    if (status != Status::kOk) {
      throw Tau2Error(source, what + " failed: camera replied " + tau2::to_string(status), status);
    }
    return reply;
  }
}

void Tau2::no_op() { transact(Function::kNoOp); }

Tau2SerialNumbers Tau2::serial_numbers() {
  const Packet r = transact(Function::kSerialNumber);
  const std::string what = "SERIAL_NUMBER reply";
  Tau2SerialNumbers s;
  s.camera =
      (uint32_t{tau2::word_at(r.payload, 0, what)} << 16) | tau2::word_at(r.payload, 1, what);
  s.sensor =
      (uint32_t{tau2::word_at(r.payload, 2, what)} << 16) | tau2::word_at(r.payload, 3, what);
  return s;
}

Tau2Revision Tau2::revision() {
  const Packet r = transact(Function::kGetRevision);
  const std::string what = "GET_REVISION reply";
  return {tau2::word_at(r.payload, 0, what), tau2::word_at(r.payload, 1, what),
          tau2::word_at(r.payload, 2, what), tau2::word_at(r.payload, 3, what)};
}

void Tau2::do_ffc() { transact(Function::kDoFfc); }

Tau2FfcMode Tau2::ffc_mode() {
  return static_cast<Tau2FfcMode>(
      tau2::word_at(transact(Function::kFfcModeSelect).payload, 0, "FFC_MODE_SELECT reply"));
}

void Tau2::set_ffc_mode(Tau2FfcMode mode) {
  transact(Function::kFfcModeSelect, tau2::words({static_cast<uint16_t>(mode)}));
}

Tau2GainMode Tau2::gain_mode() {
  return static_cast<Tau2GainMode>(
      tau2::word_at(transact(Function::kGainMode).payload, 0, "GAIN_MODE reply"));
}

void Tau2::set_gain_mode(Tau2GainMode mode) {
  transact(Function::kGainMode, tau2::words({static_cast<uint16_t>(mode)}));
}

bool Tau2::tlinear_enabled() {
  const auto sub = static_cast<uint16_t>(tau2::TlinSubcommand::kOutputEnable);
  return tau2::word_at(transact(Function::kTlinCommands, tau2::words({sub})).payload, 0,
                       "TLIN_COMMANDS reply") != 0;
}

void Tau2::set_tlinear_enabled(bool enabled) {
  const auto sub = static_cast<uint16_t>(tau2::TlinSubcommand::kOutputEnable);
  transact(Function::kTlinCommands, tau2::words({sub, static_cast<uint16_t>(enabled ? 1 : 0)}));
}

Tau2TLinearResolution Tau2::tlinear_resolution() {
  const auto sub = static_cast<uint16_t>(tau2::TlinSubcommand::kResolution);
  return static_cast<Tau2TLinearResolution>(tau2::word_at(
      transact(Function::kTlinCommands, tau2::words({sub})).payload, 0, "TLIN_COMMANDS reply"));
}

void Tau2::set_tlinear_resolution(Tau2TLinearResolution resolution) {
  const auto sub = static_cast<uint16_t>(tau2::TlinSubcommand::kResolution);
  transact(Function::kTlinCommands, tau2::words({sub, static_cast<uint16_t>(resolution)}));
}

double Tau2::fpa_temperature_c() {
  // READ_SENSOR argument 0x0000: FPA temperature as a signed word in 0.1 degC.
  const uint16_t w = tau2::word_at(transact(Function::kReadSensor, tau2::words({0x0000})).payload,
                                   0, "READ_SENSOR reply");
  return static_cast<int16_t>(w) / 10.0;
}

double Tau2::shutter_temperature_c() {
  const uint16_t w =
      tau2::word_at(transact(Function::kShutterTemp).payload, 0, "SHUTTER_TEMP reply");
  return static_cast<int16_t>(w) / 100.0;
}

void Tau2::save_settings() { transact(Function::kSetDefaults); }

// ---------------------------------------------------------------------------- emulator

std::vector<uint8_t> Tau2Emulator::feed(const uint8_t* data, size_t size) {
  pending_.insert(pending_.end(), data, data + size);
  std::vector<uint8_t> out;
  while (!pending_.empty()) {
    const ParseResult r = tau2::parse(pending_.data(), pending_.size());
    if (r.kind == ParseResult::Kind::kNeedMore) break;
    if (r.kind == ParseResult::Kind::kError) {
      // Like the camera: report the fault, then resynchronise on the next packet.
      Packet reply;
      reply.function = pending_.size() > 3 ? pending_[3] : 0;
      reply.status = static_cast<uint8_t>(
          r.error.find("CRC") != std::string::npos          ? Status::kChecksumError
          : r.error.find("byte count") != std::string::npos ? Status::kByteCountError
                                                            : Status::kUndefinedProcessError);
      pending_.clear();
      const auto bytes = reply_bytes(reply);
      out.insert(out.end(), bytes.begin(), bytes.end());
      break;
    }
    const Packet reply = handle(r.packet);
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<long>(r.consumed));
    const auto bytes = reply_bytes(reply);
    out.insert(out.end(), bytes.begin(), bytes.end());
  }
  return out;
}

std::vector<uint8_t> Tau2Emulator::reply_bytes(const Packet& reply) {
  std::vector<uint8_t> bytes = tau2::encode(reply);
  const Fault fault = fault_;
  fault_ = Fault::kNone;
  switch (fault) {
    case Fault::kNone:
      break;
    case Fault::kBadHeaderCrc:
      bytes[7] ^= 0x5A;
      break;
    case Fault::kBadPayloadCrc:
      bytes.back() ^= 0x01;
      break;
    case Fault::kWrongByteCount: {
      // A self-consistent header that announces two bytes more than follow.
      const auto n = static_cast<uint16_t>(reply.payload.size() + 2);
      bytes[4] = static_cast<uint8_t>(n >> 8);
      bytes[5] = static_cast<uint8_t>(n & 0xFF);
      const uint16_t crc1 = tau2::crc16_ccitt(bytes.data(), 6);
      bytes[6] = static_cast<uint8_t>(crc1 >> 8);
      bytes[7] = static_cast<uint8_t>(crc1 & 0xFF);
      break;
    }
    case Fault::kTruncated:
      bytes.resize(bytes.size() / 2);
      break;
    case Fault::kNoReply:
      bytes.clear();
      break;
  }
  return bytes;
}

Packet Tau2Emulator::handle(const Packet& command) {
  Packet reply;
  reply.function = command.function;
  const auto& in = command.payload;
  const auto error = [&](Status s) {
    reply.status = static_cast<uint8_t>(s);
    reply.payload.clear();
    return reply;
  };
  const auto arg = [&](size_t i) {
    return static_cast<uint16_t>((in[2 * i] << 8) | in[2 * i + 1]);
  };
  // Get (no payload) or set (one word within [0, max]) of a mode; replies with the mode.
  const auto get_set = [&](uint16_t& value, uint16_t max) {
    if (in.size() == 2) {
      if (arg(0) > max) return error(Status::kRangeError);
      value = arg(0);
    } else if (!in.empty()) {
      return error(Status::kByteCountError);
    }
    reply.payload = tau2::words({value});
    return reply;
  };

  switch (static_cast<Function>(command.function)) {
    case Function::kNoOp:
    case Function::kCameraReset:
      return reply;
    case Function::kSetDefaults:
      ++state_.settings_saved;
      return reply;
    case Function::kSerialNumber:
      reply.payload = tau2::words({static_cast<uint16_t>(state_.serial.camera >> 16),
                                   static_cast<uint16_t>(state_.serial.camera & 0xFFFF),
                                   static_cast<uint16_t>(state_.serial.sensor >> 16),
                                   static_cast<uint16_t>(state_.serial.sensor & 0xFFFF)});
      return reply;
    case Function::kGetRevision:
      reply.payload = tau2::words({state_.revision.software_major, state_.revision.software_minor,
                                   state_.revision.firmware_major, state_.revision.firmware_minor});
      return reply;
    case Function::kGainMode: {
      auto v = static_cast<uint16_t>(state_.gain_mode);
      reply = get_set(v, 3);
      state_.gain_mode = static_cast<Tau2GainMode>(v);
      return reply;
    }
    case Function::kFfcModeSelect: {
      auto v = static_cast<uint16_t>(state_.ffc_mode);
      reply = get_set(v, 2);
      state_.ffc_mode = static_cast<Tau2FfcMode>(v);
      return reply;
    }
    case Function::kDoFfc:
      ++state_.ffc_count;
      return reply;
    case Function::kReadSensor:
      if (in.size() != 2) return error(Status::kByteCountError);
      if (arg(0) != 0x0000) return error(Status::kRangeError);
      reply.payload = tau2::words({static_cast<uint16_t>(state_.fpa_temperature_c_x10)});
      return reply;
    case Function::kShutterTemp:
      if (!in.empty()) return error(Status::kByteCountError);
      reply.payload = tau2::words({static_cast<uint16_t>(state_.shutter_temperature_c_x100)});
      return reply;
    case Function::kTlinCommands: {
      if (in.size() != 2 && in.size() != 4) return error(Status::kByteCountError);
      const auto sub = static_cast<tau2::TlinSubcommand>(arg(0));
      if (sub != tau2::TlinSubcommand::kOutputEnable && sub != tau2::TlinSubcommand::kResolution) {
        return error(Status::kRangeError);
      }
      const bool is_enable = sub == tau2::TlinSubcommand::kOutputEnable;
      if (in.size() == 2) {
        reply.payload = tau2::words(
            {static_cast<uint16_t>(is_enable ? state_.tlinear_enabled
                                             : static_cast<uint16_t>(state_.tlinear_resolution))});
        return reply;
      }
      if (arg(1) > 1) return error(Status::kRangeError);
      if (is_enable) {
        state_.tlinear_enabled = arg(1) != 0;
      } else {
        state_.tlinear_resolution = static_cast<Tau2TLinearResolution>(arg(1));
      }
      return reply;  // set replies carry no payload
    }
  }
  return error(Status::kUndefinedFunctionError);
}

// ------------------------------------------------------------------------ pty emulator

Tau2PtyEmulator::Tau2PtyEmulator() {
  char name[256] = {0};
  if (::openpty(&master_fd_, &slave_fd_, name, nullptr, nullptr) != 0) {
    throw core::Error("openpty",
                      std::string("cannot create a pseudo-terminal: ") + std::strerror(errno));
  }
  path_ = name;
  // Raw mode on both sides: no echo, no CR/LF translation of binary packets.
  termios tio{};
  ::tcgetattr(slave_fd_, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(slave_fd_, TCSANOW, &tio);
  thread_ = std::thread([this] { serve(); });
}

Tau2PtyEmulator::~Tau2PtyEmulator() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  ::close(slave_fd_);
  ::close(master_fd_);
}

void Tau2PtyEmulator::serve() {
  uint8_t buf[512];
  while (!stop_.load()) {
    pollfd p{master_fd_, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0) continue;
    const ssize_t n = ::read(master_fd_, buf, sizeof buf);
    if (n <= 0) continue;
    std::vector<uint8_t> reply;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      reply = emulator_.feed(buf, static_cast<size_t>(n));
    }
    size_t done = 0;
    while (done < reply.size()) {
      const ssize_t w = ::write(master_fd_, reply.data() + done, reply.size() - done);
      if (w <= 0) break;
      done += static_cast<size_t>(w);
    }
  }
}

}  // namespace rgbdt::thermal_camera
