// rgbdt_tilt_lidar: record the raw stream of a tilting LIDAR (Hokuyo + Dynamixel tilt motor)
// into an MRPT rawlog, assemble a rawlog into one PCD per tilt, or summarise a rawlog.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/Clock.h>

#include "app_config.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/tilt_lidar/assembler.hpp"
#include "rgbdt/tilt_lidar/emulated_rig.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"
#include "rgbdt/tilt_lidar/tilt_lidar_sensor.hpp"

namespace fs = std::filesystem;
using namespace rgbdt;

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

/// A rig option of `record`: it writes one key of the INI section that the driver reads
/// (tilt_lidar_sensor.hpp), over the --ini file's value of that key. Values are kept as the
/// text given (checked as numbers by CLI11) so that an option not given stays empty: it leaves
/// the key to the INI and shows as `~` in the effective configuration.
struct RigOption {
  enum class Kind { kText, kInteger, kNumber, kPositive };
  enum class Need {
    kWithoutIni,         ///< required when there is no --ini
    kDeviceWithoutIni,   ///< required when there is no --ini, except with --emulate
    kScannerWithoutIni,  ///< one of the two scanner addresses, as kDeviceWithoutIni
    kNever,              ///< its default fits any rig: SCIP's port, the encoder rate
  };
  const char* name;
  const char* ini_key;
  const char* help;  ///< with the unit
  Kind kind;
  Need need;
};

using Kind = RigOption::Kind;
using Need = RigOption::Need;
const RigOption kRigOptions[] = {
    {"--scanner-ip", "IP_DIR", "Ethernet scanner's IPv4 address (UTM-30LX: 192.168.0.10)",
     Kind::kText, Need::kScannerWithoutIni},
    {"--scanner-port", "PORT_DIR", "its TCP port (default 10940, SCIP's)", Kind::kInteger,
     Need::kNever},
    {"--scanner-serial", "COM_port_LIN",
     "USB scanner's serial device, e.g. ttyACM0 (instead of --scanner-ip)", Kind::kText,
     Need::kScannerWithoutIni},
    {"--dxl-port", "DXL_port", "serial device of the Dynamixel bus, e.g. /dev/ttyUSB0", Kind::kText,
     Need::kDeviceWithoutIni},
    {"--dxl-baud", "DXL_baud", "the bus's baud rate [bit/s]", Kind::kInteger, Need::kWithoutIni},
    {"--dxl-id", "DXL_id", "the tilt motor's Dynamixel id (0..252)", Kind::kInteger,
     Need::kWithoutIni},
    {"--dxl-counts-per-rev", "DXL_counts_per_rev",
     "motor encoder counts per output revolution [counts/rev] (H54-200-S500-R: 501923)",
     Kind::kPositive, Need::kWithoutIni},
    {"--tilt-min-deg", "tilt_min_deg", "lower tilt limit [deg]", Kind::kNumber, Need::kWithoutIni},
    {"--tilt-max-deg", "tilt_max_deg", "upper tilt limit [deg]", Kind::kNumber, Need::kWithoutIni},
    {"--tilt-speed-deg-s", "tilt_speed_deg_s", "tilt speed [deg/s]", Kind::kPositive,
     Need::kWithoutIni},
    {"--encoder-rate-hz", "encoder_rate_hz", "encoder sampling rate [Hz] (default 200)",
     Kind::kPositive, Need::kNever},
    {"--mount-x", "mount_x", "scanner on the tilt axis (T_axis_scanner): x [m]", Kind::kNumber,
     Need::kWithoutIni},
    {"--mount-y", "mount_y", "T_axis_scanner: y [m]", Kind::kNumber, Need::kWithoutIni},
    {"--mount-z", "mount_z", "T_axis_scanner: z [m]", Kind::kNumber, Need::kWithoutIni},
    {"--mount-roll-deg", "mount_roll_deg", "T_axis_scanner: roll [deg]", Kind::kNumber,
     Need::kWithoutIni},
    {"--mount-pitch-deg", "mount_pitch_deg", "T_axis_scanner: pitch [deg]", Kind::kNumber,
     Need::kWithoutIni},
    {"--mount-yaw-deg", "mount_yaw_deg", "T_axis_scanner: yaw [deg]", Kind::kNumber,
     Need::kWithoutIni},
};
constexpr std::size_t kRigOptionCount = std::size(kRigOptions);

struct RecordArgs {
  std::string ini, section = "TILT_LIDAR", out, rig_out;
  std::array<std::string, kRigOptionCount> rig;  ///< by kRigOptions' index; empty: not given
  std::string config;                            ///< the app's --config, to name it in messages
  double duration_s = 0;
  bool emulate = false;
  int kill_scanner_at_s = -1, scanner_back_at_s = -1;  // emulated outage, for demos/tests
};

void add_rig_options(CLI::App& rec, RecordArgs& a) {
  const std::string group =
      "Rig (each sets the INI key named, over --ini's; without --ini all are required but "
      "--scanner-port and --encoder-rate-hz, and --emulate supplies the devices' addresses)";
  for (std::size_t i = 0; i < kRigOptionCount; ++i) {
    const RigOption& o = kRigOptions[i];
    CLI::Option* op =
        rec.add_option(o.name, a.rig[i], std::string(o.help) + " (INI: " + o.ini_key + ")");
    op->group(group);
    // The value stays text (see RigOption); the checks make it a number, under the number's
    // name in the help.
    if (o.kind == Kind::kInteger) {
      op->type_name("INT")->check(CLI::Validator(CLI::TypeValidator<int>()).description(""));
    }
    if (o.kind == Kind::kNumber)
      op->type_name("FLOAT")->check(CLI::Validator(CLI::Number).description(""));
    if (o.kind == Kind::kPositive) op->type_name("FLOAT")->check(CLI::PositiveNumber);
  }
  rec.get_option("--scanner-ip")->excludes("--scanner-serial");
  rec.get_option("--scanner-port")->excludes("--scanner-serial");
  rec.get_option("--scanner-port")->check(CLI::Range(1, 65535));
  rec.get_option("--dxl-baud")->check(CLI::PositiveNumber);
  rec.get_option("--dxl-id")->check(CLI::Range(0, 252));
}

/// The rig options that are required and missing: none with --ini (the INI or the driver's
/// defaults give what is not given), else every one a rig cannot do without, so that no value
/// of the paper's rig is taken for another's; the emulator supplies the devices' addresses.
std::vector<std::string> missing_rig_options(const RecordArgs& a) {
  std::vector<std::string> missing;
  if (!a.ini.empty()) return missing;
  bool scanner_given = false;
  for (std::size_t i = 0; i < kRigOptionCount; ++i) {
    const RigOption& o = kRigOptions[i];
    if (o.need == Need::kScannerWithoutIni) scanner_given = scanner_given || !a.rig[i].empty();
    const bool needed =
        o.need == Need::kWithoutIni || (o.need == Need::kDeviceWithoutIni && !a.emulate);
    if (needed && a.rig[i].empty()) missing.push_back(o.name);
  }
  if (!scanner_given && !a.emulate)
    missing.insert(missing.begin(), "--scanner-ip or --scanner-serial");
  return missing;
}

/// What the driver's configuration comes from, for its messages.
std::string rig_source(const RecordArgs& a) {
  const bool options = std::any_of(a.rig.begin(), a.rig.end(), [](auto& v) { return !v.empty(); });
  if (!options) return a.ini;
  const std::string opts =
      "record's rig options" + (a.config.empty() ? std::string() : " (and " + a.config + ")");
  return a.ini.empty() ? opts : a.ini + " with " + opts;
}

/// The INI section the driver's loadConfig reads (TiltLidarSensor, through
/// load_tilt_lidar_config): the --ini file's keys, then each rig option given over its key.
mrpt::config::CConfigFileMemory rig_section(const RecordArgs& a) {
  mrpt::config::CConfigFileMemory mem;
  if (!a.ini.empty()) {
    if (!fs::exists(a.ini)) throw core::Error(a.ini, "INI file does not exist");
    const mrpt::config::CConfigFile ini(a.ini);
    if (!ini.sectionExists(a.section)) {
      throw core::Error(a.ini, "has no section [" + a.section + "] (--section)");
    }
    std::vector<std::string> keys;
    ini.getAllKeys(a.section, keys);
    for (const auto& k : keys) mem.write(a.section, k, ini.read_string(a.section, k, ""));
  }
  for (std::size_t i = 0; i < kRigOptionCount; ++i) {
    if (a.rig[i].empty()) continue;
    const std::string key = kRigOptions[i].ini_key;
    mem.write(a.section, key, a.rig[i]);
    // The scanner is on one address: the one given replaces the INI's other.
    if (key == "IP_DIR") mem.write(a.section, "COM_port_LIN", "");
    if (key == "COM_port_LIN") mem.write(a.section, "IP_DIR", "");
  }
  return mem;
}

/// Starts an emulated UTM-30LX and Dynamixel PRO in-process and points the driver's section at
/// them; the INI and the options still give the motor, geometry, limits and speeds.
std::unique_ptr<tilt_lidar::EmulatedRig> start_emulated_rig(mrpt::config::CConfigFileMemory& mem,
                                                            const std::string& section) {
  tilt_lidar::EmulatedRigOptions eo;
  eo.motor.table.counts_per_revolution =
      mem.read_double(section, "DXL_counts_per_rev", eo.motor.table.counts_per_revolution);
  eo.motor.id = static_cast<std::uint8_t>(std::clamp(mem.read_int(section, "DXL_id", 1), 0, 252));
  auto emu = std::make_unique<tilt_lidar::EmulatedRig>(eo);
  mem.write(section, "IP_DIR", "127.0.0.1");
  mem.write(section, "PORT_DIR", emu->hokuyo_port());
  mem.write(section, "COM_port_LIN", "");
  mem.write(section, "DXL_port", emu->motor_device());
  std::printf("emulating: UTM-30LX on 127.0.0.1:%d, Dynamixel PRO on %s\n", emu->hokuyo_port(),
              emu->motor_device().c_str());
  return emu;
}

int record(const RecordArgs& a) {
  if (const auto missing = missing_rig_options(a); !missing.empty()) {
    std::string list;
    for (const auto& m : missing) list += (list.empty() ? "" : ", ") + m;
    throw std::invalid_argument(
        "record: without --ini the rig is described by options, and these are missing: " + list +
        " (on the command line or in a --config YAML such as config/tilt_lidar_paper_rig.yaml), "
        "or give --ini FILE");
  }
  mrpt::config::CConfigFileMemory mem = rig_section(a);
  const std::string source = rig_source(a);
  std::unique_ptr<tilt_lidar::EmulatedRig> emu;
  if (a.emulate) emu = start_emulated_rig(mem, a.section);
  const tilt_lidar::TiltLidarConfig cfg =
      tilt_lidar::load_tilt_lidar_config(mem, a.section, source);
  const std::string rig_out = a.rig_out.empty()
                                  ? (fs::path(a.out).replace_extension(".tilt_rig.yaml")).string()
                                  : a.rig_out;
  core::write_tilt_rig(rig_out, cfg.rig);

  tilt_lidar::RawlogWriterOptions wo;
  wo.labels = {cfg.scan_label, cfg.encoder_label};
  tilt_lidar::RawlogWriter writer(a.out, cfg.rig, wo);
  tilt_lidar::Assembler assembler(cfg.rig);  // live tilt statistics only
  tilt_lidar::TiltLidarSensor sensor;
  sensor.set_config(cfg);
  sensor.setSensorLabel(a.section);
  sensor.initialize();
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  const auto t_start = std::chrono::steady_clock::now();
  auto t_report = t_start;
  tilt_lidar::TiltLidarStats last{};
  std::int64_t tilts = 0, last_tilts = 0;
  bool outage_done = false, back_done = false;
  std::printf("recording to %s (rig: %s); Ctrl-C stops\n", a.out.c_str(), rig_out.c_str());
  while (!g_stop) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    if (a.duration_s > 0 && elapsed >= a.duration_s) break;
    if (emu && a.kill_scanner_at_s >= 0 && !outage_done && elapsed >= a.kill_scanner_at_s) {
      std::printf("[emulation] scanner switched off\n");
      emu->hokuyo().stop();
      outage_done = true;
    }
    if (emu && a.scanner_back_at_s >= 0 && outage_done && !back_done &&
        elapsed >= a.scanner_back_at_s) {
      std::printf("[emulation] scanner switched on again\n");
      emu->hokuyo().start();
      back_done = true;
    }
    sensor.doProcess();
    for (const auto& [stamp, obj] : sensor.getObservations()) {
      const auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj);
      if (!obs) continue;
      writer.write(*obs);
      std::vector<tilt_lidar::TiltCloud> done;
      if (const auto* s = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(obs.get())) {
        done = assembler.add_scan(tilt_lidar::from_observation(*s));
      } else if (const auto* d = dynamic_cast<const mrpt::obs::CObservationRawDAQ*>(obs.get())) {
        done = assembler.add_encoder_sample(tilt_lidar::from_observation(*d, cfg.rig.motor));
      }
      tilts += static_cast<std::int64_t>(done.size());
    }
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - t_report).count();
    if (dt >= 1.0) {
      const auto s = sensor.stats();
      const auto& as = assembler.stats();
      std::printf(
          "t=%6.1fs  scans/s %5.1f  encoder/s %6.1f  tilts/s %4.2f  | dropped: scans %lld, encoder "
          "reads %lld, "
          "beams %lld | scanner %s, motor %s\n",
          std::chrono::duration<double>(now - t_start).count(), (s.scans - last.scans) / dt,
          (s.encoder_samples - last.encoder_samples) / dt, (tilts - last_tilts) / dt,
          static_cast<long long>(s.scans_missed), static_cast<long long>(s.encoder_failures),
          static_cast<long long>(as.dropped_gap + as.dropped_no_encoder),
          s.scanner_ok ? "ok" : "LOST", s.motor_ok ? "ok" : "LOST");
      std::fflush(stdout);
      last = s;
      last_tilts = tilts;
      t_report = now;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  sensor.stop();
  for (const auto& [stamp, obj] : sensor.getObservations()) {
    if (const auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj))
      writer.write(*obs);
  }
  writer.close();
  const auto s = sensor.stats();
  std::printf(
      "recorded %lld records: %lld scans (%lld missed), %lld encoder samples (%lld failed reads), "
      "scanner lost %lld times -> %s\n",
      static_cast<long long>(writer.records()), static_cast<long long>(s.scans),
      static_cast<long long>(s.scans_missed), static_cast<long long>(s.encoder_samples),
      static_cast<long long>(s.encoder_failures), static_cast<long long>(s.scanner_losses),
      a.out.c_str());
  return s.scans > 0 && s.encoder_samples > 0 ? 0 : 1;
}

struct AssembleArgs {
  std::string rawlog, rig, out;
  tilt_lidar::AssemblerOptions options;
  bool keep_partial = false;
};

// The rig file of a rawlog: --rig if given, else `<stem>.tilt_rig.yaml` (what `record`
// writes), else `tilt_rig.yaml` (what `rgbdt_sim mapping` writes) beside the rawlog.
std::string find_rig(const AssembleArgs& a) {
  if (!a.rig.empty()) {
    std::printf("rig: %s (--rig)\n", a.rig.c_str());
    return a.rig;
  }
  const fs::path rawlog(a.rawlog);
  const fs::path stem_rig = fs::path(rawlog).replace_extension(".tilt_rig.yaml");
  const fs::path dir_rig = rawlog.parent_path() / "tilt_rig.yaml";
  for (const auto& [p, why] : {std::pair{stem_rig, "beside the rawlog, named after it"},
                               std::pair{dir_rig, "beside the rawlog"}}) {
    if (fs::is_regular_file(p)) {
      std::printf("rig: %s (%s)\n", p.c_str(), why);
      return p.string();
    }
  }
  throw core::Error(a.rawlog, "no --rig given and neither " + stem_rig.string() +
                                  " (written by `record`) nor " + dir_rig.string() +
                                  " (written by `rgbdt_sim mapping`) exists; pass --rig FILE");
}

int assemble(const AssembleArgs& a) {
  const std::string rig_path = find_rig(a);
  const core::TiltRig rig = core::read_tilt_rig(rig_path);
  tilt_lidar::Assembler assembler(rig, a.options);
  // Absolute paths: index rows are written relative to the index's own folder, whatever
  // the working directory.
  const fs::path clouds = fs::absolute(fs::path(a.out) / "clouds");
  const fs::path index_path = clouds / "index.csv";
  fs::create_directories(clouds);
  // index.csv is the completion marker: a stale one from an earlier run goes first, so a
  // run that fails leaves no index that lists clouds it did not write.
  core::remove_stale_output(index_path.string());
  // Clouds of an earlier run (NNNNNN.pcd) would mix with this run's: removed.
  for (const auto& e : fs::directory_iterator(clouds)) {
    const std::string n = e.path().filename().string();
    if (n.size() == 10 && n.compare(6, 4, ".pcd") == 0 &&
        std::all_of(n.begin(), n.begin() + 6, [](char c) { return c >= '0' && c <= '9'; })) {
      core::remove_stale_output(e.path().string());
    }
  }
  core::install_interrupt_handler();
  // For tests of Ctrl-C: the app sends itself SIGINT after this many clouds.
  const char* interrupt_env = std::getenv("RGBDT_TEST_INTERRUPT_AFTER_CLOUDS");
  const long interrupt_after = interrupt_env ? std::strtol(interrupt_env, nullptr, 10) : 0;
  std::vector<core::TimedFile> index;
  std::int64_t skipped = 0;
  const auto r = tilt_lidar::replay_rawlog(
      a.rawlog, assembler,
      [&](tilt_lidar::TiltCloud&& t) {
        if (core::interrupted()) return;  // stop after the cloud being written
        if (t.partial && !a.keep_partial) {
          ++skipped;
          return;
        }
        char name[32];
        std::snprintf(name, sizeof name, "%06zu.pcd", index.size());
        const fs::path file = clouds / name;
        core::TempOutput out(file.string());
        cloud::save_pcd(out.temp_path(), *t.cloud);
        out.commit();
        index.push_back({t.start_time_s, file.string()});
        std::printf("tilt %4zu  %s  %7zu points  %2d scans  %.3f..%.3f s  %s\n", index.size() - 1,
                    name, t.cloud->size(), t.stats.scans, t.start_time_s, t.end_time_s,
                    t.direction > 0 ? "up" : "down");
        std::fflush(stdout);
        if (interrupt_after > 0 && static_cast<long>(index.size()) == interrupt_after)
          std::raise(SIGINT);
      },
      {}, [] { return core::interrupted(); });
  // Rows name the clouds relative to the index's folder (they all live in it).
  std::ostringstream csv;
  csv << "time_s,file\n" << std::setprecision(15);
  for (const auto& e : index)
    csv << e.time_s << ',' << fs::path(e.file).filename().string() << '\n';
  core::write_file_atomic(index_path.string(), csv.str());
  const auto& s = assembler.stats();
  std::printf(
      "%lld scans, %lld encoder samples -> %zu tilts in %s (%lld partial skipped)\n"
      "points %lld, invalid %lld (%lld NaN/negative ranges refused), dropped in encoder gaps %lld, "
      "without encoder %lld, duplicates %lld/%lld, late %lld/%lld\n",
      static_cast<long long>(r.scans), static_cast<long long>(r.encoder_samples), index.size(),
      index_path.c_str(), static_cast<long long>(skipped), static_cast<long long>(s.points),
      static_cast<long long>(s.invalid), static_cast<long long>(r.beams_refused),
      static_cast<long long>(s.dropped_gap), static_cast<long long>(s.dropped_no_encoder),
      static_cast<long long>(s.scans_duplicate), static_cast<long long>(s.encoder_duplicate),
      static_cast<long long>(s.scans_late), static_cast<long long>(s.encoder_late));
  if (r.interrupted) {
    std::fprintf(
        stderr,
        "interrupted: %zu complete tilt clouds are written and listed in %s; the rest of %s was "
        "not assembled\n",
        index.size(), index_path.c_str(), a.rawlog.c_str());
    return 130;
  }
  if (r.truncated) {
    std::fprintf(
        stderr,
        "error: %s\n(the %zu tilts before the damaged record were written and indexed in %s)\n",
        r.error.c_str(), index.size(), index_path.c_str());
    return 2;
  }
  if (index.empty()) {
    std::fprintf(
        stderr,
        "error: %s: no complete tilt could be assembled (%lld scans, %lld encoder samples)\n",
        a.rawlog.c_str(), static_cast<long long>(r.scans),
        static_cast<long long>(r.encoder_samples));
    return 1;
  }
  return 0;
}

int info(const std::string& rawlog) {
  const auto s = tilt_lidar::summarize_rawlog(rawlog);
  std::printf("%s: %lld observations\n", rawlog.c_str(), static_cast<long long>(s.observations));
  std::printf("%-16s %-40s %8s %18s %18s %9s\n", "label", "class", "count", "first [s]", "last [s]",
              "rate [Hz]");
  for (const auto& [label, st] : s.streams) {
    const double span = st.last_time_s - st.first_time_s;
    std::printf("%-16s %-40s %8lld %18.6f %18.6f %9.2f\n", label.empty() ? "(none)" : label.c_str(),
                st.class_name.c_str(), static_cast<long long>(st.count), st.first_time_s,
                st.last_time_s, span > 0 ? (st.count - 1) / span : 0.0);
  }
  if (s.truncated) {
    std::fprintf(stderr, "error: %s\n", s.error.c_str());
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_tilt_lidar: tilting-LIDAR recorder and assembler.\n"
      "  record    drive the scanner (MRPT CHokuyoURG) and the Dynamixel tilt motor, write the "
      "raw\n"
      "            stream (HOKUYO scans + TILT_ENCODER samples) to an MRPT rawlog\n"
      "  assemble  turn a raw rawlog into one PCD per tilt plus clouds/index.csv\n"
      "  info      list the streams of a rawlog (any MRPT rawlog)"};
  apps::add_config_option(app, argc, argv,
                          "the MRPT rawlog-grabber INI of the rig is given with `record --ini "
                          "FILE` (formerly `record --config`)");
  app.require_subcommand(1);
  app.fallthrough();  // global options may also follow the command (`record --config F`)
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "show library log messages (debug level)");

  RecordArgs ra;
  auto* rec = app.add_subcommand("record", "record the raw stream to an MRPT rawlog");
  rec->add_option("--ini", ra.ini,
                  "MRPT rawlog-grabber INI of the rig (keys: see tilt_lidar_sensor.hpp); the rig "
                  "options below override its keys");
  rec->add_option("--section", ra.section, "INI section of the tilting LIDAR")
      ->capture_default_str();
  rec->add_option("--out", ra.out, "output rawlog")->required();
  rec->add_option("--rig-out", ra.rig_out, "tilt_rig.yaml to write (default: <out>.tilt_rig.yaml)");
  rec->add_option("--duration", ra.duration_s,
                  "stop after this many seconds (default: until Ctrl-C)");
  rec->add_flag("--emulate", ra.emulate,
                "use an emulated UTM-30LX and Dynamixel PRO (no hardware)");
  rec->add_option("--emulate-outage", ra.kill_scanner_at_s,
                  "with --emulate: switch the scanner off at this second");
  rec->add_option("--emulate-return", ra.scanner_back_at_s,
                  "with --emulate: switch it on again at this second");
  add_rig_options(*rec, ra);

  AssembleArgs aa;
  auto* asmb = app.add_subcommand("assemble", "assemble a raw rawlog into one PCD per tilt");
  asmb->add_option("rawlog", aa.rawlog, "input rawlog")->required()->check(CLI::ExistingFile);
  asmb->add_option(
          "--rig", aa.rig,
          "tilt_rig.yaml (frames, beam timing, encoder); default: <rawlog stem>.tilt_rig.yaml "
          "(written by `record`), else tilt_rig.yaml (written by `rgbdt_sim mapping`) beside the "
          "rawlog")
      ->check(CLI::ExistingFile);
  asmb->add_option("--out", aa.out, "output folder (clouds/NNNNNN.pcd, clouds/index.csv)")
      ->required();
  asmb->add_option("--max-gap", aa.options.max_encoder_gap_s,
                   "longest encoder gap to interpolate across [s]")
      ->capture_default_str();
  asmb->add_option("--encoder-offset", aa.options.encoder_time_offset_s,
                   "encoder clock -> scanner clock offset [s]")
      ->capture_default_str();
  double hysteresis_deg = aa.options.reversal_hysteresis_rad * 180.0 / M_PI;
  asmb->add_option("--hysteresis-deg", hysteresis_deg, "reversal detection hysteresis [deg]")
      ->check(CLI::PositiveNumber);
  asmb->add_flag("--keep-partial", aa.keep_partial,
                 "also write the incomplete first and last tilts");

  std::string info_path;
  auto* inf = app.add_subcommand("info", "summarise a rawlog");
  inf->add_option("rawlog", info_path, "input rawlog")->required()->check(CLI::ExistingFile);

  CLI11_PARSE(app, argc, argv);
  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(verbose ? core::LogLevel::kDebug : core::LogLevel::kWarning);
  try {
    if (*rec) {
      if (app.get_config_ptr()->count() > 0) ra.config = app.get_config_ptr()->as<std::string>();
      return record(ra);
    }
    if (*asmb) {
      aa.options.reversal_hysteresis_rad = hysteresis_deg * M_PI / 180.0;
      if (const auto why = aa.options.validate(); !why.empty()) throw std::invalid_argument(why);
      return assemble(aa);
    }
    if (*inf) return info(info_path);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 1;
}
