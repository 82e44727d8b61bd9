#pragma once
/// \file
/// A complete emulated tilting LIDAR for demos and end-to-end tests: an EmulatedMotor on a
/// pseudo-terminal and a HokuyoEmulator on 127.0.0.1 whose ranges are ray-cast, beam by
/// beam, in a box-shaped room at the motor's actual tilt (closed loop: the scans follow
/// whatever the sweep controller makes the motor do).
#include <memory>
#include <string>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/tilt_lidar/dynamixel_emulator.hpp"
#include "rgbdt/tilt_lidar/hokuyo_emulator.hpp"

namespace rgbdt::tilt_lidar {

/// Axis-aligned room around the tilt axis (lidar frame) [m].
struct RoomSpec {
  double x_min = -6.0, x_max = 8.0, y_min = -4.0, y_max = 5.0, z_min = -1.2, z_max = 2.6;
  /// Distance along a ray from `origin` in unit direction `dir` to the first wall.
  double range(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const;
};

struct EmulatedRigOptions {
  core::TiltRig rig;             ///< geometry used for the ray casting (motor counts ignored)
  RoomSpec room;
  int hokuyo_port = 0;           ///< 0 = any free port
  dxl::EmulatedMotorOptions motor;
};

class EmulatedRig {
 public:
  explicit EmulatedRig(const EmulatedRigOptions& options = {});
  ~EmulatedRig();
  const std::string& motor_device() const { return motor_->device(); }
  int hokuyo_port() const { return hokuyo_->port(); }
  HokuyoEmulator& hokuyo() { return *hokuyo_; }
  dxl::EmulatedMotor& motor() { return *motor_; }
  const EmulatedRigOptions& options() const { return options_; }

 private:
  EmulatedRigOptions options_;
  std::unique_ptr<dxl::EmulatedMotor> motor_;
  std::unique_ptr<HokuyoEmulator> hokuyo_;
};

}  // namespace rgbdt::tilt_lidar
