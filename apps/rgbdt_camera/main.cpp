// rgbdt_camera: list GenICam cameras, record frames to PNG with a time index, and control
// a FLIR Tau2 over its serial channel.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <sstream>
#include <thread>

#include "app_config.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/thermal_camera/frame_recorder.hpp"
#include "rgbdt/thermal_camera/genicam_camera.hpp"
#include "rgbdt/thermal_camera/tau2.hpp"

namespace tc = rgbdt::thermal_camera;
namespace core = rgbdt::core;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

tc::InterfaceSelection parse_interfaces(const std::string& list) {
  tc::InterfaceSelection s{false, false, false};
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item == "none") {
      continue;
    } else if (item == "gige") {
      s.gige = true;
    } else if (item == "usb3") {
      s.usb3 = true;
    } else if (item == "fake") {
      s.fake = true;
    } else {
      throw std::invalid_argument("--interfaces: unknown interface '" + item +
                                  "' (expected gige, usb3, fake or none)");
    }
  }
  return s;
}

int run_list(const std::string& interfaces) {
  tc::select_interfaces(parse_interfaces(interfaces));
  const auto devices = tc::list_devices();
  if (devices.empty()) {
    std::cout << "no cameras found on: " << interfaces << "\n";
    return 0;
  }
  std::printf("%-32s %-11s %-16s %-20s %-12s %s\n", "ID", "PROTOCOL", "VENDOR", "MODEL", "SERIAL",
              "ADDRESS");
  for (const auto& d : devices) {
    std::printf("%-32s %-11s %-16s %-20s %-12s %s\n", d.id.c_str(), d.protocol.c_str(),
                d.vendor.c_str(), d.model.c_str(), d.serial.c_str(), d.address.c_str());
  }
  return 0;
}

struct RecordArgs {
  std::string id;
  std::string out;
  std::string interfaces = "gige,usb3";
  long frames = 0;
  double seconds = 0.0;
  std::string pixel_format;
  std::vector<int> roi;
  double rate_hz = 0.0;
  double exposure_us = 0.0;
  int timeout_ms = 1000;
  // Frames the stream can hold while a PNG is being written: 64 cover 0.64 s of stall at
  // 100 Hz (a busy host) for ~42 MB at 640x512 Mono16.
  int buffers = 64;
  double give_up_s = 30.0;
  bool raw_bayer = false;
  std::string clock = "host";
  int png_compression = 1;
};

// Every problem of the record arguments at once, each naming its option and value; empty
// when they are usable. Checked before the camera is opened or anything is written.
std::string record_problems(const RecordArgs& a) {
  std::ostringstream why;
  const auto finite_non_negative = [&](const char* option, double v, const char* zero_means) {
    if (!(std::isfinite(v) && v >= 0.0)) {
      why << "\n  " << option << " " << v << ": expected a finite value >= 0 (0: " << zero_means
          << ")";
    }
  };
  finite_non_negative("--rate", a.rate_hz, "keep the camera's");
  finite_non_negative("--exposure", a.exposure_us, "keep the camera's");
  finite_non_negative("--give-up", a.give_up_s, "never");
  if (a.timeout_ms < 1) why << "\n  --timeout-ms " << a.timeout_ms << ": expected >= 1";
  if (a.buffers < 2 || a.buffers > 4096) {
    why << "\n  --buffers " << a.buffers << ": expected 2..4096";
  }
  if (!a.roi.empty()) {
    if (a.roi.size() != 4) {
      why << "\n  --roi: " << a.roi.size() << " values, expected x,y,width,height";
    } else if (a.roi[0] < 0 || a.roi[1] < 0 || a.roi[2] < 0 || a.roi[3] < 0) {
      why << "\n  --roi " << a.roi[0] << "," << a.roi[1] << "," << a.roi[2] << "," << a.roi[3]
          << ": expected values >= 0 (width, height 0: up to the sensor edge)";
    }
  }
  if (a.id.empty()) why << "\n  --id is empty, expected a camera id from `list` or an address";
  std::error_code ec;
  if (a.out.empty()) {
    why << "\n  --out is empty, expected a folder for the recording";
  } else if (fs::exists(a.out, ec) && !fs::is_directory(a.out, ec)) {
    why << "\n  --out " << a.out << ": exists and is not a folder";
  } else if (fs::exists(fs::path(a.out) / "index.csv", ec)) {
    why << "\n  --out " << a.out << ": holds a recording (index.csv); choose an empty folder";
  }
  return why.str();
}

int run_record(const RecordArgs& a) {
  if (const std::string why = record_problems(a); !why.empty()) {
    throw std::invalid_argument("record: bad arguments, nothing was recorded:" + why);
  }
  tc::select_interfaces(parse_interfaces(a.interfaces));
  tc::GenicamOptions options;
  options.pixel_format = a.pixel_format;
  if (!a.roi.empty()) {
    options.region = tc::Region{a.roi[0], a.roi[1], a.roi[2], a.roi[3]};
  }
  options.frame_rate_hz = a.rate_hz;
  options.exposure_us = a.exposure_us;
  options.timeout_ms = a.timeout_ms;
  options.buffer_count = a.buffers;

  tc::GenicamCamera camera(a.id, options);
  const tc::DeviceInfo info = camera.info();
  std::cerr << "camera " << a.id << ": " << info.vendor << " " << info.model << " serial "
            << info.serial << ", " << camera.pixel_format() << " " << camera.region().width << "x"
            << camera.region().height << "\n";
  tc::FrameRecorderOptions ro;
  ro.out_dir = a.out;
  ro.demosaic_bayer = !a.raw_bayer;
  ro.png_compression = a.png_compression;
  tc::FrameRecorder recorder(ro);

  core::install_interrupt_handler();
  camera.start();
  const auto t_start = Clock::now();
  auto t_report = t_start;
  auto t_lost = Clock::time_point{};
  bool lost = false;
  int exit_code = 0;
  bool gave_up = false;
  std::string last_status = "streaming";
  std::string last_message;  // status lines are printed when they change
  while (!core::interrupted() && !gave_up) {
    const double elapsed_s = std::chrono::duration<double>(Clock::now() - t_start).count();
    if (a.seconds > 0 && elapsed_s >= a.seconds) break;
    if (a.frames > 0 && static_cast<long>(recorder.frames_written()) >= a.frames) break;

    tc::GrabResult r = camera.grab();
    switch (r.status) {
      case tc::GrabStatus::kFrame: {
        const uint64_t stamp_ns =
            a.clock == "device" ? r.frame.device_timestamp_ns : r.frame.host_timestamp_ns;
        recorder.write(r.frame, static_cast<double>(stamp_ns) * 1e-9);
        lost = false;
        last_status = "streaming";
        break;
      }
      case tc::GrabStatus::kDisconnected:
        if (!lost) {
          lost = true;
          t_lost = Clock::now();
          recorder.flush_index();  // everything written so far is listed
        }
        if (r.message != last_message) std::cerr << "status: " << r.message << "\n";
        last_message = r.message;
        last_status = "disconnected";
        if (a.give_up_s > 0 &&
            std::chrono::duration<double>(Clock::now() - t_lost).count() > a.give_up_s) {
          std::cerr << "error: camera " << a.id << " did not come back within " << a.give_up_s
                    << " s\n";
          exit_code = 3;
          gave_up = true;
        }
        break;
      case tc::GrabStatus::kReconnected:
        std::cerr << "status: " << r.message << "\n";
        last_message.clear();
        lost = false;
        break;
      case tc::GrabStatus::kIncomplete:
      case tc::GrabStatus::kTimeout:
        last_status = tc::to_string(r.status);
        break;
    }
    if (Clock::now() - t_report >= std::chrono::seconds(1)) {
      t_report = Clock::now();
      const auto s = camera.statistics();
      std::fprintf(stderr, "frames %zu  fps %.1f  lost %llu  incomplete %llu  timeouts %llu  %s\n",
                   recorder.frames_written(), s.frame_rate_hz,
                   static_cast<unsigned long long>(s.frames_lost),
                   static_cast<unsigned long long>(s.frames_incomplete),
                   static_cast<unsigned long long>(s.timeouts), last_status.c_str());
    }
  }
  camera.stop();
  recorder.flush_index();
  const auto s = camera.statistics();
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - t_start).count();
  std::cout << "recorded " << recorder.frames_written() << " frames in " << elapsed_s << " s to "
            << recorder.index_path() << "\n"
            << "lost " << s.frames_lost << ", incomplete " << s.frames_incomplete << ", timeouts "
            << s.timeouts << ", disconnects " << s.disconnects << ", reconnects " << s.reconnects
            << "\n";
  if (core::interrupted()) std::cout << "stopped by signal " << core::interrupt_signal() << "\n";
  if (exit_code == 0 && a.frames > 0 && static_cast<long>(recorder.frames_written()) < a.frames &&
      !core::interrupted()) {
    std::cerr << "error: recorded " << recorder.frames_written() << " of the " << a.frames
              << " frames asked for with --frames\n";
    exit_code = 1;
  }
  return exit_code;
}

struct Tau2Args {
  std::string port;
  bool usb = false;
  std::string usb_serial;
  int baud = 57600;
  bool ffc = false;
  std::string tlinear;  // on|off|high|low
  std::string gain;     // auto|low|high|manual
  bool save = false;
};

int run_tau2(const Tau2Args& a) {
  if (a.baud <= 0) {
    throw std::invalid_argument("tau2: --baud " + std::to_string(a.baud) +
                                ": expected a positive baud rate (the Tau2 uses 57600 or 921600)");
  }
  std::unique_ptr<tc::SerialTransport> transport;
  if (a.usb) {
    tc::FtdiUsbOptions o;
    o.serial = a.usb_serial;
    o.baud = a.baud;
    transport = std::make_unique<tc::FtdiUsbTransport>(o);
  } else {
    if (a.port.empty()) throw std::invalid_argument("tau2: give --port DEVICE or --usb");
    transport = std::make_unique<tc::TermiosTransport>(a.port, a.baud);
  }
  tc::Tau2 camera(std::move(transport));
  if (!a.gain.empty()) {
    const std::map<std::string, tc::Tau2GainMode> modes = {{"auto", tc::Tau2GainMode::kAutomatic},
                                                           {"low", tc::Tau2GainMode::kLowGain},
                                                           {"high", tc::Tau2GainMode::kHighGain},
                                                           {"manual", tc::Tau2GainMode::kManual}};
    camera.set_gain_mode(modes.at(a.gain));
  }
  if (a.tlinear == "on" || a.tlinear == "off") camera.set_tlinear_enabled(a.tlinear == "on");
  if (a.tlinear == "high") camera.set_tlinear_resolution(tc::Tau2TLinearResolution::kHigh);
  if (a.tlinear == "low") camera.set_tlinear_resolution(tc::Tau2TLinearResolution::kLow);
  if (a.ffc) camera.do_ffc();
  if (a.save) camera.save_settings();

  const auto serial = camera.serial_numbers();
  const auto rev = camera.revision();
  const bool tlinear = camera.tlinear_enabled();
  const auto resolution = camera.tlinear_resolution();
  static const char* kGain[] = {"auto", "low", "high", "manual"};
  static const char* kFfc[] = {"manual", "auto", "external"};
  const auto gain = static_cast<unsigned>(camera.gain_mode());
  const auto ffc = static_cast<unsigned>(camera.ffc_mode());
  std::printf("camera serial  %u\nsensor serial  %u\nsoftware       %u.%u\nfirmware       %u.%u\n",
              serial.camera, serial.sensor, rev.software_major, rev.software_minor,
              rev.firmware_major, rev.firmware_minor);
  std::printf("gain mode      %s\nffc mode       %s\n", gain < 4 ? kGain[gain] : "?",
              ffc < 3 ? kFfc[ffc] : "?");
  std::printf("tlinear        %s, %.2f K/count\n", tlinear ? "on" : "off",
              tc::kelvin_per_count(resolution));
  std::printf("fpa temp       %.1f degC\nshutter temp   %.2f degC\n", camera.fpa_temperature_c(),
              camera.shutter_temperature_c());
  return 0;
}

int run_tau2_emulate() {
  tc::Tau2PtyEmulator emulator;
  core::install_interrupt_handler();
  std::cout << "emulated Tau2 on " << emulator.path() << " (Ctrl-C to stop)" << std::endl;
  while (!core::interrupted()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::cout << "served "
            << emulator.with_emulator([](tc::Tau2Emulator& e) { return e.state().ffc_count; })
            << " FFC command(s)\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_camera: GenICam (GigE/USB3 Vision) cameras through Aravis and FLIR Tau2 control.\n"
      "  list    show the cameras Aravis finds\n"
      "  record  write frames as PNG (16-bit for Mono16/thermal, 8-bit otherwise) with\n"
      "          index.csv (time_s,file); Ctrl-C stops cleanly, a lost camera is reopened\n"
      "  tau2    query/configure a Tau2 core over its serial port (tty or FTDI via libusb)\n"
      "  tau2-emulate  serve a software Tau2 on a pseudo-terminal (no hardware)"};
  rgbdt::apps::add_config_option(app, argc, argv);
  app.require_subcommand(1);
  app.fallthrough();  // --config may also follow the command

  std::string list_interfaces = "gige,usb3";
  auto* list = app.add_subcommand("list", "List the cameras Aravis can see");
  list->add_option("--interfaces", list_interfaces, "Comma list of gige, usb3, fake")
      ->capture_default_str();

  RecordArgs r;
  auto* record = app.add_subcommand("record", "Record frames to PNG files with a time index");
  record->add_option("--id", r.id, "Camera id from `list`, or a GigE camera's IPv4 address")
      ->required();
  record->add_option("--out", r.out, "Output folder (created; must not hold a recording)")
      ->required();
  auto* frames_opt =
      record->add_option("--frames", r.frames, "Stop after N frames")->check(CLI::PositiveNumber);
  auto* seconds_opt = record->add_option("--seconds", r.seconds, "Stop after S seconds")
                          ->check(CLI::PositiveNumber);
  frames_opt->excludes(seconds_opt);
  // Unset means no limit: no default to show (0 is no valid count) or for --config to name.
  frames_opt->default_str("");
  seconds_opt->default_str("");
  record
      ->add_option(
          "--interfaces", r.interfaces,
          "Comma list of gige, usb3, fake, or none (a GigE camera given by IP address needs none)")
      ->capture_default_str();
  record->add_option("--pixel-format", r.pixel_format,
                     "Mono8, Mono16, BayerRG8, ... (default: keep)");
  record->add_option("--roi", r.roi, "Region x,y,width,height [px] (default: keep)")
      ->delimiter(',')
      ->expected(4)
      ->default_str("");
  record->add_option("--rate", r.rate_hz, "Frame rate [Hz] (default: keep)");
  record->add_option("--exposure", r.exposure_us, "Exposure [us] (default: keep)");
  record->add_option("--timeout-ms", r.timeout_ms, "Frame timeout [ms]")->capture_default_str();
  record
      ->add_option("--buffers", r.buffers,
                   "Frame buffers in the stream's pool: how long a stall in writing (a busy "
                   "host) is absorbed before frames are lost, e.g. 64 at 100 Hz = 0.64 s")
      ->capture_default_str();
  record
      ->add_option("--give-up", r.give_up_s,
                   "Stop if a lost camera is not back after S seconds (0: never)")
      ->capture_default_str();
  record->add_flag("--raw-bayer", r.raw_bayer, "Write Bayer mosaics as they come (no demosaicing)");
  record->add_option("--clock", r.clock, "Index times from the host or the device clock")
      ->check(CLI::IsMember({"host", "device"}))
      ->capture_default_str();
  record->add_option("--png-compression", r.png_compression, "0..9")
      ->check(CLI::Range(0, 9))
      ->capture_default_str();

  Tau2Args t;
  auto* tau2 =
      app.add_subcommand("tau2", "Query and configure a FLIR Tau2 over its serial channel");
  tau2->add_option("--port", t.port, "Serial device, e.g. /dev/ttyUSB0");
  tau2->add_flag("--usb", t.usb,
                 "Talk to the FTDI bridge directly through libusb instead of a tty");
  tau2->add_option("--usb-serial", t.usb_serial, "USB serial string of the bridge (with --usb)");
  tau2->add_option("--baud", t.baud, "Baud rate")->capture_default_str();
  tau2->add_flag("--ffc", t.ffc, "Run a flat-field correction");
  tau2->add_option("--tlinear", t.tlinear, "on, off (TLinear output) or high, low (resolution)")
      ->check(CLI::IsMember({"on", "off", "high", "low"}));
  tau2->add_option("--gain", t.gain, "auto, low, high, manual")
      ->check(CLI::IsMember({"auto", "low", "high", "manual"}));
  tau2->add_flag("--save", t.save, "Store the current settings as power-on defaults");

  auto* emulate = app.add_subcommand("tau2-emulate",
                                     "Serve an emulated Tau2 on a pseudo-terminal until Ctrl-C");

  CLI11_PARSE(app, argc, argv);
  rgbdt::core::set_log_sink(rgbdt::core::stderr_log_sink);
  rgbdt::core::set_log_level(rgbdt::core::LogLevel::kWarning);
  try {
    if (*list) return run_list(list_interfaces);
    if (*record) return run_record(r);
    if (*tau2) return run_tau2(t);
    if (*emulate) return run_tau2_emulate();
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
