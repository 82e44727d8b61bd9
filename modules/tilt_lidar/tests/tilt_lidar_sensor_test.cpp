// End to end: the CGenericSensor with MRPT's CHokuyoURG and the Dynamixel sweep, against
// the emulated rig (UTM-30LX on loopback TCP + Dynamixel PRO on a pty, ray-cast room).
#include "rgbdt/tilt_lidar/tilt_lidar_sensor.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/tilt_lidar/emulated_rig.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::tilt_lidar {
namespace {

using namespace std::chrono_literals;

TEST(TiltLidarConfig, ReadsARawlogGrabberStyleIni) {
  // MRPT's own Hokuyo section (shared/data/mrpt) plus the tilt keys: CHokuyoURG's key names
  // carry over unchanged.
  const std::string path = std::string(RGBDT_SHARED_DATA_DIR) + "/mrpt/config_files/rawlog-grabber/hokuyo_UTM.ini";
  mrpt::config::CConfigFile shared(path);
  ASSERT_TRUE(shared.sectionExists("LASER_2D")) << "missing test data " << path;
  mrpt::config::CConfigFileMemory ini;
  std::vector<std::string> keys;
  shared.getAllKeys("LASER_2D", keys);
  for (const auto& k : keys) ini.write("LASER_2D", k, shared.read_string("LASER_2D", k, ""));
  ini.write("LASER_2D", "DXL_port", "/dev/ttyUSB0");
  ini.write("LASER_2D", "tilt_min_deg", -25);
  ini.write("LASER_2D", "mount_z", 0.05);
  const TiltLidarConfig c = load_tilt_lidar_config(ini, "LASER_2D", path);
  EXPECT_EQ(c.hokuyo.serial_port, "ttyACM0");
  EXPECT_TRUE(c.hokuyo.ip_address.empty());
  EXPECT_NEAR(c.sweep.lower_rad, -25 * M_PI / 180, 1e-12);
  EXPECT_NEAR(c.rig.T_axis_scanner.translation().z(), 0.05, 1e-12);
  EXPECT_EQ(c.rig.motor.counts_per_revolution, 501923.0);

  ini.write("LASER_2D", "IP_DIR", "192.168.0.10");  // and COM_port_LIN: ambiguous
  try {
    load_tilt_lidar_config(ini, "LASER_2D", path);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("IP_DIR"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("LASER_2D"), std::string::npos) << e.what();
  }
}

// Real time with threads, sockets and a pty; generous waits keep it valid on a loaded CI.
TEST(TiltLidarSensor, RecordsThroughAScannerOutageAndReconnects) {
  EmulatedRig emu;
  TiltLidarConfig cfg;
  cfg.hokuyo.ip_address = "127.0.0.1";
  cfg.hokuyo.port = emu.hokuyo_port();
  cfg.motor_port = emu.motor_device();
  cfg.rig.motor.counts_per_revolution = cfg.sweep.table.counts_per_revolution;
  const auto dir = test::temp_dir("rec");
  const std::string path = (dir / "s.rawlog").string();
  RawlogWriter writer(path, cfg.rig);
  TiltLidarSensor sensor;
  sensor.set_config(cfg);
  sensor.initialize();
  auto pump = [&](auto done, std::chrono::seconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline && !done()) {
      sensor.doProcess();
      for (const auto& [t, obj] : sensor.getObservations()) {
        if (auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj)) writer.write(*o);
      }
      std::this_thread::sleep_for(10ms);
    }
    return done();
  };
  ASSERT_TRUE(pump([&] { return sensor.stats().scans >= 40; }, 20s));
  emu.hokuyo().stop();
  EXPECT_TRUE(pump([&] { return sensor.stats().scanner_losses >= 1; }, 10s));
  const auto at_loss = sensor.stats();
  EXPECT_FALSE(at_loss.scanner_ok);
  emu.hokuyo().start();
  EXPECT_TRUE(pump([&] { return sensor.stats().scans >= at_loss.scans + 40; }, 20s));
  sensor.stop();
  for (const auto& [t, obj] : sensor.getObservations()) {  // what arrived after the last pump
    if (auto o = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj)) writer.write(*o);
  }
  writer.close();
  const auto s = sensor.stats();
  EXPECT_EQ(s.scanner_losses, 1);
  EXPECT_GT(s.encoder_samples, 100);

  // The file is intact and readable to the end, and assembles into tilts whose points lie
  // on the room's walls: error budget = stamp offset between emulator and driver (~1-2 ms
  // of tilt at 1.2 rad/s, at <= 10 m: ~2.5 cm) plus the emulator's extrapolation at the
  // turns (12.5 mrad: up to 12 cm at 10 m, few points); median well below 5 cm.
  Assembler assembler(cfg.rig);
  std::vector<double> wall_dist;
  const auto r = replay_rawlog(path, assembler, [&](TiltCloud&& t) {
    const RoomSpec room;
    for (const auto& p : t.cloud->points) {
      const double d = std::min({std::abs(p.x - room.x_min), std::abs(p.x - room.x_max), std::abs(p.y - room.y_min),
                                 std::abs(p.y - room.y_max), std::abs(p.z - room.z_min), std::abs(p.z - room.z_max)});
      wall_dist.push_back(d);
    }
  });
  EXPECT_FALSE(r.truncated) << r.error;
  EXPECT_EQ(r.scans, s.scans);
  EXPECT_GE(r.tilts, 2);
  ASSERT_GT(wall_dist.size(), 10000u);
  std::nth_element(wall_dist.begin(), wall_dist.begin() + wall_dist.size() / 2, wall_dist.end());
  EXPECT_LT(wall_dist[wall_dist.size() / 2], 0.05);
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
