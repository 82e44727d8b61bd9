#include "rgbdt/tilt_lidar/tilt_lidar_sensor.hpp"

#include <chrono>
#include <cmath>
#include <sstream>

#include <mrpt/core/Clock.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose3D.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"
#include "rgbdt/tilt_lidar/serial_port.hpp"

IMPLEMENTS_GENERIC_SENSOR(TiltLidarSensor, rgbdt::tilt_lidar)

namespace rgbdt::tilt_lidar {

namespace {

constexpr double kDeg = M_PI / 180.0;

}  // namespace

std::string TiltLidarConfig::validate() const {
  if (const auto w = hokuyo.validate(); !w.empty()) return w;
  if (motor_port.empty()) return "DXL_port (the tilt motor's serial device) is not set";
  if (const auto w = bus.validate(); !w.empty()) return w;
  if (const auto w = sweep.validate(); !w.empty()) return w;
  if (!(encoder_rate_hz > 0 && encoder_rate_hz <= 2000)) return "encoder_rate_hz " + std::to_string(encoder_rate_hz) + " must be in (0, 2000]";
  if (scan_label.empty() || encoder_label.empty() || scan_label == encoder_label) return "scan and encoder labels must be set and differ";
  return {};
}

TiltLidarConfig load_tilt_lidar_config(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                                       const std::string& source) {
  const std::string where = source + " [" + section + "]";
  if (!ini.sectionExists(section)) throw core::Error(where, "section not found");
  TiltLidarConfig c;
  c.hokuyo.ip_address = ini.read_string(section, "IP_DIR", "");
  c.hokuyo.port = ini.read_int(section, "PORT_DIR", 10940);
  c.hokuyo.serial_port = ini.read_string(section, "COM_port_LIN", "");
  if (!c.hokuyo.ip_address.empty() && !c.hokuyo.serial_port.empty()) {
    throw core::Error(where, "both IP_DIR and COM_port_LIN are set; the scanner is on one of them");
  }
  c.hokuyo.intensity = ini.read_bool(section, "intensity", false);
  c.scan_label = ini.read_string(section, "scan_sensorLabel", c.scan_label);
  c.encoder_label = ini.read_string(section, "encoder_sensorLabel", c.encoder_label);
  c.hokuyo.sensor_label = c.scan_label;
  c.scan_time_offset_s = ini.read_double(section, "scan_time_offset_s", c.scan_time_offset_s);
  c.motor_port = ini.read_string(section, "DXL_port", "");
  c.motor_baud = ini.read_int(section, "DXL_baud", c.motor_baud);
  c.bus.timeout_ms = ini.read_int(section, "DXL_timeout_ms", c.bus.timeout_ms);
  c.bus.retries = ini.read_int(section, "DXL_retries", c.bus.retries);
  const int id = ini.read_int(section, "DXL_id", 1);
  if (id < 0 || id > 252) throw core::Error(where, "DXL_id " + std::to_string(id) + " must be in 0..252");
  c.sweep.id = static_cast<std::uint8_t>(id);
  auto& t = c.sweep.table;
  t.counts_per_revolution = ini.read_double(section, "DXL_counts_per_rev", t.counts_per_revolution);
  t.rpm_per_velocity_unit = ini.read_double(section, "DXL_rpm_per_unit", t.rpm_per_velocity_unit);
  t.torque_enable = static_cast<std::uint16_t>(ini.read_int(section, "DXL_addr_torque_enable", t.torque_enable));
  t.goal_position = static_cast<std::uint16_t>(ini.read_int(section, "DXL_addr_goal_position", t.goal_position));
  t.goal_velocity = static_cast<std::uint16_t>(ini.read_int(section, "DXL_addr_goal_velocity", t.goal_velocity));
  t.present_position = static_cast<std::uint16_t>(ini.read_int(section, "DXL_addr_present_position", t.present_position));
  c.sweep.lower_rad = ini.read_double(section, "tilt_min_deg", -20.0) * kDeg;
  c.sweep.upper_rad = ini.read_double(section, "tilt_max_deg", 20.0) * kDeg;
  c.sweep.speed_rad_s = ini.read_double(section, "tilt_speed_deg_s", 70.0) * kDeg;
  c.encoder_rate_hz = ini.read_double(section, "encoder_rate_hz", c.encoder_rate_hz);
  c.rig.motor.counts_per_revolution = t.counts_per_revolution;
  c.rig.motor.zero_count = 0.0;
  c.rig.T_axis_scanner = core::make_transform(
      core::rotation_from_rpy(ini.read_double(section, "mount_roll_deg", 0.0) * kDeg,
                              ini.read_double(section, "mount_pitch_deg", 0.0) * kDeg,
                              ini.read_double(section, "mount_yaw_deg", 0.0) * kDeg),
      {ini.read_double(section, "mount_x", 0.0), ini.read_double(section, "mount_y", 0.0),
       ini.read_double(section, "mount_z", 0.0)});
  if (const auto why = c.validate(); !why.empty()) throw core::Error(where, why);
  return c;
}

TiltLidarSensor::TiltLidarSensor() { m_sensorLabel = "TILT_LIDAR"; }

TiltLidarSensor::~TiltLidarSensor() { stop(); }

void TiltLidarSensor::loadConfig_sensorSpecific(const mrpt::config::CConfigFileBase& ini, const std::string& section) {
  config_ = load_tilt_lidar_config(ini, section, "INI");
}

void TiltLidarSensor::initialize() {
  if (const auto why = config_.validate(); !why.empty()) throw std::invalid_argument("TiltLidarSensor: " + why);
  if (running_) return;
  running_ = true;
  m_state = ssInitializing;
  motor_thread_ = std::thread([this] { motor_loop(); });
  scanner_thread_ = std::thread([this] { scanner_loop(); });
}

void TiltLidarSensor::stop() {
  running_ = false;
  if (scanner_thread_.joinable()) scanner_thread_.join();
  if (motor_thread_.joinable()) motor_thread_.join();
}

void TiltLidarSensor::doProcess() {
  const TiltLidarStats s = stats();
  m_state = (s.scanner_ok && s.motor_ok) ? ssWorking : (s.scans + s.encoder_samples > 0 ? ssError : ssInitializing);
}

TiltLidarStats TiltLidarSensor::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

bool TiltLidarSensor::tilt_at(double t, double& phi) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (recent_.size() < 2) return false;
  // Linear interpolation, or extrapolation from the last two samples (the scan may be
  // a few ms ahead of the newest encoder reading).
  std::size_t k = 1;
  while (k + 1 < recent_.size() && recent_[k].time_s < t) ++k;
  const EncoderSample& a = recent_[k - 1];
  const EncoderSample& b = recent_[k];
  if (b.time_s <= a.time_s) return false;
  phi = a.angle_rad + (b.angle_rad - a.angle_rad) * (t - a.time_s) / (b.time_s - a.time_s);
  return true;
}

void TiltLidarSensor::scanner_loop() {
  HokuyoScanner scanner(config_.hokuyo);
  bool connected = false;
  double last_scan_s = -1.0;
  const double period = config_.rig.scanner.scan_period_s;
  auto set_ok = [this](bool ok) {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.scanner_ok = ok;
  };
  while (running_) {
    if (!connected) {
      connected = scanner.start();
      set_ok(connected);
      if (!connected) {
        core::log_warning("tilt_lidar: scanner not available (", scanner.last_error(), "); retrying");
        for (int k = 0; k < 10 && running_; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(50));
        continue;
      }
      core::log_info("tilt_lidar: scanner connected");
    }
    auto obs = mrpt::obs::CObservation2DRangeScan::Create();
    const HokuyoScanner::Poll r = scanner.poll(*obs);
    if (r == HokuyoScanner::Poll::kDeviceError) {
      bool lost = false;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        ++stats_.scanner_errors;
        if (stats_.scanner_ok) {
          stats_.scanner_ok = false;
          ++stats_.scanner_losses;
          lost = true;
        }
      }
      if (lost) core::log_error("tilt_lidar: scanner lost (", scanner.last_error(), "); recording continues, reconnecting");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    if (r != HokuyoScanner::Poll::kScan) continue;
    const double t = mrpt::Clock::toDouble(obs->timestamp) + config_.scan_time_offset_s;
    obs->timestamp = mrpt::Clock::fromDouble(t);
    obs->sensorLabel = config_.scan_label;
    double phi = 0.0;
    const Eigen::Isometry3d T = tilt_at(t, phi) ? config_.rig.T_lidar_scanner(phi) : config_.rig.T_axis_scanner;
    mrpt::math::CMatrixDouble44 M;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) M(i, j) = T.matrix()(i, j);
    obs->sensorPose = mrpt::poses::CPose3D(M);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!stats_.scanner_ok) core::log_info("tilt_lidar: scanner back");
      stats_.scanner_ok = true;
      ++stats_.scans;
      if (last_scan_s > 0 && t - last_scan_s > 1.5 * period) {
        stats_.scans_missed += static_cast<std::int64_t>(std::lround((t - last_scan_s) / period)) - 1;
      }
    }
    last_scan_s = t;
    appendObservation(obs);
  }
}

void TiltLidarSensor::motor_loop() {
  const auto period = std::chrono::duration<double>(1.0 / config_.encoder_rate_hz);
  while (running_) {
    std::unique_ptr<SerialPort> port;
    try {
      port = std::make_unique<SerialPort>(config_.motor_port, config_.motor_baud);
      dxl::DynamixelBus bus(*port, config_.bus);
      dxl::SweepController sweep(bus, config_.sweep, [] { return mrpt::Clock::nowDouble(); });
      sweep.start();
      core::log_info("tilt_lidar: tilt motor sweeping on ", config_.motor_port);
      int failures_in_row = 0;
      auto next = std::chrono::steady_clock::now();
      while (running_) {
        next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
        const auto reading = sweep.step();
        {
          std::lock_guard<std::mutex> lock(mutex_);
          if (reading) {
            ++stats_.encoder_samples;
            stats_.motor_ok = true;
            recent_.push_back(reading->sample);
            while (recent_.size() > 64) recent_.pop_front();
            failures_in_row = 0;
          } else {
            ++stats_.encoder_failures;
            ++failures_in_row;
            if (failures_in_row > 20) stats_.motor_ok = false;
          }
        }
        if (reading) {
          appendObservation(to_observation(reading->sample, static_cast<double>(reading->count), config_.encoder_label));
        }
        std::this_thread::sleep_until(next);
        if (std::chrono::steady_clock::now() > next + std::chrono::milliseconds(100)) next = std::chrono::steady_clock::now();
      }
      sweep.stop();
    } catch (const std::exception& e) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        stats_.motor_ok = false;
      }
      core::log_error("tilt_lidar: tilt motor: ", e.what(), "; retrying");
      for (int k = 0; k < 10 && running_; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
}

}  // namespace rgbdt::tilt_lidar
