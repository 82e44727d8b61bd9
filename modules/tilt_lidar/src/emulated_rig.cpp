#include "rgbdt/tilt_lidar/emulated_rig.hpp"

#include <cmath>
#include <limits>

namespace rgbdt::tilt_lidar {

double RoomSpec::range(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  double best = std::numeric_limits<double>::infinity();
  const double lo[3] = {x_min, y_min, z_min}, hi[3] = {x_max, y_max, z_max};
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-12) continue;
    const double t = ((d[a] > 0 ? hi[a] : lo[a]) - o[a]) / d[a];
    if (t > 0) best = std::min(best, t);
  }
  return best;
}

EmulatedRig::EmulatedRig(const EmulatedRigOptions& options) : options_(options) {
  motor_ = std::make_unique<dxl::EmulatedMotor>(options_.motor);
  HokuyoEmulatorOptions ho;
  ho.port = options_.hokuyo_port;
  ho.scan_period_s = options_.rig.scanner.scan_period_s;
  ho.keep_served = 64;
  const core::TiltRig rig = options_.rig;
  const RoomSpec room = options_.room;
  dxl::EmulatedMotor* motor = motor_.get();
  // The scan is sent when complete: beam i was measured at now - period + i * dt. The tilt
  // at that time is extrapolated from the motor's present angle and velocity: exact while
  // cruising; at the turns (acceleration a) off by up to a * period^2 / 2 (12.5 mrad at
  // 40 rad/s^2).
  ho.device.steps_per_revolution = rig.scanner.steps_per_revolution;
  ho.device.last_step = rig.scanner.beams - 1;
  ho.device.front_step = (rig.scanner.beams - 1) / 2;
  hokuyo_ = std::make_unique<HokuyoEmulator>(
      [rig, room, motor](std::int64_t, double) {
        const double phi_now = motor->angle_rad();
        const double v = motor->velocity_rad_s();
        const int n = rig.scanner.beams;
        scip::ScanFrame f;
        f.ranges_mm.resize(static_cast<std::size_t>(n));
        for (int i = 0; i < n; ++i) {
          const double dt = -rig.scanner.scan_period_s + rig.scanner.beam_time_offset(i);
          const double phi = phi_now + v * dt;
          const Eigen::Isometry3d T = rig.T_lidar_scanner(phi);
          const double th = rig.scanner.beam_angle(i);
          const Eigen::Vector3d dir = T.linear() * Eigen::Vector3d(std::cos(th), std::sin(th), 0.0);
          const double r = room.range(T.translation(), dir);
          f.ranges_mm[static_cast<std::size_t>(i)] =
              std::isfinite(r) && r < 30.0 ? static_cast<std::uint32_t>(std::lround(r * 1000.0)) : 0;
        }
        return f;
      },
      ho);
  hokuyo_->start();
}

EmulatedRig::~EmulatedRig() {
  hokuyo_->stop();
}

}  // namespace rgbdt::tilt_lidar
