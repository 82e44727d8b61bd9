#pragma once
/// \file
/// An IMU beside the LIDAR: its samples (session.yaml's `imu`, CSV time_s,wx,wy,wz,ax,ay,az)
/// and the LIDAR's rotation they give, for the odometry's rotation prior
/// (Odometry::set_rotation_prior).
#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

#include "rgbdt/rgbdt_map/trajectory.hpp"

namespace rgbdt::rgbdt_map {

struct ImuSample {
  double time_s = 0.0;            ///< session clock [s]
  Eigen::Vector3d gyro_rad_s;     ///< angular rate in the IMU's axes [rad/s]
  Eigen::Vector3d accel_m_s2;     ///< specific force in the IMU's axes [m/s^2]
};

/// The most rows read_imu_csv accepts: 10 h at 1 kHz (a bound on memory, ~2 GB).
constexpr std::size_t kMaxImuSamples = 36000000;

/// Reads CSV "time_s,wx,wy,wz,ax,ay,az" (header line optional). Throws rgbdt::core::Error
/// naming the file and line when a row does not hold 7 finite numbers, a time is not after
/// the previous one, or the file holds more than kMaxImuSamples rows.
std::vector<ImuSample> read_imu_csv(const std::string& path);

/// The LIDAR's rotation from the gyro: poses T_frame_lidar (translation zero) at every
/// sample's time, in a frame fixed to the LIDAR at the first sample, integrated with the
/// mean rate of each pair of samples. `rotation_lidar_imu` is the IMU's axes in the LIDAR
/// frame. Only relative rotations over a tilt are meant to be used: the gyro's bias makes
/// the rotation drift (0.1 deg/s of bias: 0.06 deg over a 0.6 s tilt).
/// Throws std::invalid_argument with fewer than 2 samples.
Trajectory gyro_rotation_track(const std::vector<ImuSample>& samples,
                               const Eigen::Quaterniond& rotation_lidar_imu);

/// The longest time between two consecutive samples [s] (0 with fewer than 2).
double largest_imu_gap_s(const std::vector<ImuSample>& samples);

}  // namespace rgbdt::rgbdt_map
