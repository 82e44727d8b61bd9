#pragma once
/// \file
/// Camera control of a FLIR Tau2 core over its serial command channel (protocol in
/// tau2_protocol.hpp; function codes and scalings from the FLIR Tau 2 / Quark 2 Software
/// IDD, 102-PS242-43). Video is separate: 14-bit LVDS/CMOS through a frame grabber, or a
/// UVC Y16 stream on USB accessory boards (see the module README).
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rgbdt/thermal_camera/serial_transport.hpp"
#include "rgbdt/thermal_camera/tau2_protocol.hpp"

namespace rgbdt::thermal_camera {

/// The camera answered a command with a status other than CAM_OK, or did not answer.
class Tau2Error : public core::Error {
 public:
  Tau2Error(const std::string& source, const std::string& message, tau2::Status status)
      : core::Error(source, message), status_(status) {}
  tau2::Status status() const { return status_; }

 private:
  tau2::Status status_;
};

enum class Tau2GainMode : uint16_t { kAutomatic = 0, kLowGain = 1, kHighGain = 2, kManual = 3 };
enum class Tau2FfcMode : uint16_t { kManual = 0, kAutomatic = 1, kExternal = 2 };
enum class Tau2TLinearResolution : uint16_t {
  kLow = 0,   ///< 0.4 K per count
  kHigh = 1,  ///< 0.04 K per count
};
/// Kelvin per count of a TLinear resolution (for Radiometry's linear model).
double kelvin_per_count(Tau2TLinearResolution resolution);

struct Tau2SerialNumbers {
  uint32_t camera = 0;
  uint32_t sensor = 0;
};

struct Tau2Revision {
  uint16_t software_major = 0, software_minor = 0;
  uint16_t firmware_major = 0, firmware_minor = 0;
};

struct Tau2Options {
  int reply_timeout_ms = 1000;  ///< per command; FFC replies within ~0.5 s on a Tau2
  int busy_retries = 3;         ///< CAM_BUSY replies are retried this many times
  std::string validate() const;
};

class Tau2 {
 public:
  /// Takes ownership of the transport. Throws std::invalid_argument for bad options or a
  /// null transport. Does not talk to the camera yet.
  explicit Tau2(std::unique_ptr<SerialTransport> transport, const Tau2Options& options = {});

  /// Sends one command and returns the reply. Throws tau2::ProtocolError for a corrupt
  /// reply (bad CRC, wrong length, truncated), Tau2Error for a status other than CAM_OK,
  /// a reply to another function, or no reply within reply_timeout_ms.
  tau2::Packet transact(tau2::Function function, const std::vector<uint8_t>& payload = {});

  void no_op();
  Tau2SerialNumbers serial_numbers();
  Tau2Revision revision();
  void do_ffc();
  Tau2FfcMode ffc_mode();
  void set_ffc_mode(Tau2FfcMode mode);
  Tau2GainMode gain_mode();
  void set_gain_mode(Tau2GainMode mode);
  bool tlinear_enabled();
  void set_tlinear_enabled(bool enabled);
  Tau2TLinearResolution tlinear_resolution();
  void set_tlinear_resolution(Tau2TLinearResolution resolution);
  double fpa_temperature_c();      ///< focal plane array [degC], 0.1 degC steps
  double shutter_temperature_c();  ///< shutter [degC], 0.01 degC steps
  void save_settings();            ///< SET_DEFAULTS: current settings become power-on ones

  SerialTransport& transport() { return *transport_; }

 private:
  std::unique_ptr<SerialTransport> transport_;
  Tau2Options options_;
};

/// A software Tau2: answers command packets like the camera does, with settable state.
/// For tests (on a pseudo-terminal or in memory) and demos without hardware.
class Tau2Emulator {
 public:
  /// Damage to inject into the next reply (one-shot), to test the host's checks.
  enum class Fault { kNone, kBadHeaderCrc, kBadPayloadCrc, kWrongByteCount, kTruncated, kNoReply };

  struct State {
    Tau2SerialNumbers serial{123456, 654321};
    Tau2Revision revision{2, 1, 3, 4};
    Tau2GainMode gain_mode = Tau2GainMode::kAutomatic;
    Tau2FfcMode ffc_mode = Tau2FfcMode::kAutomatic;
    bool tlinear_enabled = false;
    Tau2TLinearResolution tlinear_resolution = Tau2TLinearResolution::kHigh;
    int16_t fpa_temperature_c_x10 = 312;        ///< 31.2 degC
    int16_t shutter_temperature_c_x100 = 2987;  ///< 29.87 degC
    int ffc_count = 0;                          ///< DO_FFC commands received
    int settings_saved = 0;                     ///< SET_DEFAULTS commands received
  };

  /// Feeds bytes from the host; returns the reply bytes to send back (possibly several
  /// packets, or none while a packet is incomplete). A corrupt host packet is answered
  /// with CAM_CHECKSUM_ERROR or CAM_BYTE_COUNT_ERROR and its bytes are dropped.
  std::vector<uint8_t> feed(const uint8_t* data, size_t size);

  void inject_fault(Fault fault) { fault_ = fault; }
  State& state() { return state_; }
  const State& state() const { return state_; }

 private:
  tau2::Packet handle(const tau2::Packet& command);
  std::vector<uint8_t> reply_bytes(const tau2::Packet& reply);

  State state_;
  std::vector<uint8_t> pending_;
  Fault fault_ = Fault::kNone;
};

/// A Tau2Emulator served on a pseudo-terminal by a background thread: open path() with
/// TermiosTransport (or any serial tool) as if it were the camera's port. For tests and
/// for developing against a "camera" without hardware (`rgbdt_camera tau2-emulate`).
class Tau2PtyEmulator {
 public:
  /// Opens the pty and starts serving. Throws rgbdt::core::Error if no pty is available.
  Tau2PtyEmulator();
  ~Tau2PtyEmulator();
  Tau2PtyEmulator(const Tau2PtyEmulator&) = delete;
  Tau2PtyEmulator& operator=(const Tau2PtyEmulator&) = delete;

  /// The slave side, e.g. "/dev/pts/7".
  const std::string& path() const { return path_; }

  /// Runs fn(Tau2Emulator&) under the emulator's lock (to read or change its state or
  /// inject a fault while it serves) and returns what fn returns.
  template <typename Fn>
  auto with_emulator(Fn&& fn) {
    std::lock_guard<std::mutex> lock(mutex_);
    return fn(emulator_);
  }

 private:
  void serve();

  int master_fd_ = -1;
  int slave_fd_ = -1;  // kept open so the pty survives clients closing it
  std::string path_;
  std::mutex mutex_;
  Tau2Emulator emulator_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace rgbdt::thermal_camera
