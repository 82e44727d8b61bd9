#pragma once
/// \file
/// The tilting LIDAR as an MRPT sensor (mrpt::hwdrivers::CGenericSensor), configured from
/// a rawlog-grabber-style INI section and emitting the raw stream of tilt_rig.hpp:
/// CObservation2DRangeScan ("HOKUYO", sensorPose = the scanner's pose in the lidar frame at
/// beam 0) and CObservationRawDAQ ("TILT_ENCODER"). The scanner runs through MRPT's
/// CHokuyoURG, the motor through Dynamixel Protocol 2.0; each has its own thread.
///
/// INI keys (section given to loadConfig; CHokuyoURG's own key names for the scanner):
///   sensorLabel, process_rate            CGenericSensor's (process_rate: doProcess rate)
///   IP_DIR = 192.168.0.10, PORT_DIR = 10940   Ethernet scanner, or
///   COM_port_LIN = ttyACM0                    USB scanner
///   intensity = false                         ME instead of MD
///   scan_sensorLabel = HOKUYO, encoder_sensorLabel = TILT_ENCODER
///   scan_time_offset_s = -0.025     arrival stamp -> beam-0 time (one scan period earlier)
///   DXL_port = /dev/ttyUSB0, DXL_baud = 1000000, DXL_id = 1, DXL_timeout_ms = 20, DXL_retries = 2
///   DXL_counts_per_rev = 501923, DXL_rpm_per_unit = 0.00199234   (Dynamixel PRO H54-200)
///   DXL_addr_torque_enable = 562, DXL_addr_goal_position = 596, DXL_addr_goal_velocity = 600,
///   DXL_addr_present_position = 611
///   tilt_min_deg = -20, tilt_max_deg = 20, tilt_speed_deg_s = 70, encoder_rate_hz = 200
///   mount_x, mount_y, mount_z [m], mount_roll_deg, mount_pitch_deg, mount_yaw_deg  (T_axis_scanner)
#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/hwdrivers/CGenericSensor.h>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/tilt_lidar/dynamixel.hpp"
#include "rgbdt/tilt_lidar/hokuyo.hpp"

namespace rgbdt::tilt_lidar {

struct TiltLidarConfig {
  HokuyoOptions hokuyo;
  std::string scan_label = "HOKUYO";
  std::string encoder_label = "TILT_ENCODER";
  double scan_time_offset_s = -0.025;  ///< added to the driver's stamp to get beam 0's time
  std::string motor_port;              ///< serial device of the Dynamixel bus
  int motor_baud = 1000000;
  dxl::BusOptions bus;
  dxl::SweepOptions sweep;
  double encoder_rate_hz = 200.0;
  core::TiltRig rig;  ///< mount from the INI; motor counts = the control table's resolution
  std::string validate() const;
};

/// Reads a section; throws rgbdt::core::Error naming `source`, the section and the key.
TiltLidarConfig load_tilt_lidar_config(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                                       const std::string& source);

/// Live counters (thread-safe snapshot).
struct TiltLidarStats {
  std::int64_t scans = 0;
  std::int64_t scans_missed = 0;       ///< gaps in the scan timestamps (> 1.5 periods)
  std::int64_t scanner_errors = 0;     ///< polls that found the device unreachable
  std::int64_t scanner_losses = 0;     ///< times the scanner went away
  std::int64_t encoder_samples = 0;
  std::int64_t encoder_failures = 0;   ///< motor reads without a valid reply
  bool scanner_ok = false, motor_ok = false;
};

class TiltLidarSensor : public mrpt::hwdrivers::CGenericSensor {
  DEFINE_GENERIC_SENSOR(TiltLidarSensor)

 public:
  TiltLidarSensor();
  ~TiltLidarSensor() override;

  /// Configuration without an INI (loadConfig() fills it from one).
  void set_config(const TiltLidarConfig& config) { config_ = config; }
  const TiltLidarConfig& config() const { return config_; }

  /// Starts the scanner and motor threads. Devices that are not there yet are retried by
  /// the threads (reported through stats() and the log), so recording can start first.
  void initialize() override;
  /// Updates the sensor state; observations are queued by the threads as they arrive.
  void doProcess() override;
  /// Stops both threads and switches the motor's torque off.
  void stop();

  TiltLidarStats stats() const;

 protected:
  void loadConfig_sensorSpecific(const mrpt::config::CConfigFileBase& ini, const std::string& section) override;

 private:
  void scanner_loop();
  void motor_loop();
  bool tilt_at(double t, double& phi) const;

  TiltLidarConfig config_;
  std::atomic<bool> running_{false};
  std::thread scanner_thread_, motor_thread_;
  mutable std::mutex mutex_;
  std::deque<EncoderSample> recent_;  // for the per-scan sensor pose
  TiltLidarStats stats_;
};

}  // namespace rgbdt::tilt_lidar
