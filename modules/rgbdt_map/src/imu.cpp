#include "rgbdt/rgbdt_map/imu.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

#include "rgbdt/core/error.hpp"

namespace rgbdt::rgbdt_map {

namespace {

constexpr const char* kColumns = "time_s,wx,wy,wz,ax,ay,az";

// The 7 numbers of one row; throws naming the file, the line and the cell.
std::array<double, 7> parse_row(const std::string& path, int line_number, const std::string& line) {
  std::array<double, 7> values{};
  std::size_t count = 0, start = 0;
  const auto where = [&] { return "line " + std::to_string(line_number) + ": "; };
  while (start <= line.size()) {
    const std::size_t comma = std::min(line.find(',', start), line.size());
    const std::string cell = line.substr(start, comma - start);
    if (count == values.size()) {
      throw core::Error(path, where() + "more than 7 values (expected " + std::string(kColumns) + ")");
    }
    char* end = nullptr;
    const double v = std::strtod(cell.c_str(), &end);
    if (cell.empty() || end == cell.c_str() || *end != '\0' || !std::isfinite(v)) {
      throw core::Error(path, where() + "'" + cell + "' is not a finite number (expected " +
                                  std::string(kColumns) + ")");
    }
    values[count++] = v;
    start = comma + 1;
  }
  if (count != values.size()) {
    throw core::Error(path, where() + std::to_string(count) + " values, expected 7 (" + kColumns + ")");
  }
  return values;
}

}  // namespace

std::vector<ImuSample> read_imu_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw core::Error(path, std::string("cannot open the IMU samples (expected a CSV ") + kColumns + ")");
  std::vector<ImuSample> samples;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (line_number == 1 && line.find_first_of("abcdefghijklmnopqrstuvwxyz") != std::string::npos) continue;
    const std::array<double, 7> v = parse_row(path, line_number, line);
    if (!samples.empty() && !(v[0] > samples.back().time_s)) {
      throw core::Error(path, "line " + std::to_string(line_number) + ": time " + std::to_string(v[0]) +
                                  " s is not after the previous sample's (" +
                                  std::to_string(samples.back().time_s) + " s)");
    }
    if (samples.size() == kMaxImuSamples) {
      throw core::Error(path, "more than " + std::to_string(kMaxImuSamples) +
                                  " samples (10 h at 1 kHz); split the recording");
    }
    samples.push_back({v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6]}});
  }
  if (in.bad()) throw core::Error(path, "read error");
  return samples;
}

Trajectory gyro_rotation_track(const std::vector<ImuSample>& samples,
                               const Eigen::Quaterniond& rotation_lidar_imu) {
  if (samples.size() < 2) {
    throw std::invalid_argument("gyro_rotation_track: " + std::to_string(samples.size()) +
                                " IMU samples, expected at least 2");
  }
  const Eigen::Matrix3d R_lidar_imu = rotation_lidar_imu.normalized().toRotationMatrix();
  std::vector<TimedPose> poses;
  poses.reserve(samples.size());
  // R_frame_imu, with the frame at the first sample's LIDAR: R_frame_lidar = R_frame_imu R_imu_lidar.
  Eigen::Matrix3d R_frame_imu = R_lidar_imu;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (k > 0) {
      const double dt = samples[k].time_s - samples[k - 1].time_s;
      const Eigen::Vector3d w = 0.5 * (samples[k - 1].gyro_rad_s + samples[k].gyro_rad_s);
      const double angle = w.norm() * dt;
      if (angle > 0.0) R_frame_imu = R_frame_imu * Eigen::AngleAxisd(angle, w.normalized()).toRotationMatrix();
      // Keep it a rotation over long recordings.
      R_frame_imu = Eigen::Quaterniond(R_frame_imu).normalized().toRotationMatrix();
    }
    TimedPose pose;
    pose.time_s = samples[k].time_s;
    pose.T_world_lidar.linear() = R_frame_imu * R_lidar_imu.transpose();
    poses.push_back(pose);
  }
  return Trajectory(std::move(poses));
}

double largest_imu_gap_s(const std::vector<ImuSample>& samples) {
  double gap = 0.0;
  for (std::size_t k = 1; k < samples.size(); ++k) gap = std::max(gap, samples[k].time_s - samples[k - 1].time_s);
  return gap;
}

}  // namespace rgbdt::rgbdt_map
