// The IMU samples' reader and the LIDAR rotation integrated from the gyro.
#include "rgbdt/rgbdt_map/imu.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/transform.hpp"

namespace rgbdt::rgbdt_map {
namespace {

namespace fs = std::filesystem;

fs::path write_csv(const std::string& name, const std::string& text) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "ImuCsv";
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}

// The message of the core::Error that reading `text` throws ("" when it reads).
std::string read_error(const std::string& text) {
  try {
    read_imu_csv(write_csv("bad.csv", text).string());
  } catch (const core::Error& e) {
    return e.what();
  }
  return "";
}

TEST(ImuCsv, ReadsTheSamplesOfTheHeaderedCsv) {
  const auto samples = read_imu_csv(
      write_csv("ok.csv", "time_s,wx,wy,wz,ax,ay,az\n1.0,0.1,0.2,0.3,0,0,9.81\n1.005,-1e-3,0,0,1,2,3\r\n")
          .string());
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_EQ(samples[0].time_s, 1.0);
  EXPECT_EQ(samples[0].gyro_rad_s, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(samples[0].accel_m_s2, Eigen::Vector3d(0, 0, 9.81));
  EXPECT_EQ(samples[1].gyro_rad_s, Eigen::Vector3d(-1e-3, 0, 0));
  EXPECT_NEAR(largest_imu_gap_s(samples), 0.005, 1e-12);
}

TEST(ImuCsv, BadRowsNameTheFileTheLineAndTheValue) {
  const std::string header = "time_s,wx,wy,wz,ax,ay,az\n1,0,0,0,0,0,9.8\n";
  const struct {
    std::string row, expected;
  } cases[] = {
      {"2,0,0,0,0,9.8\n", "line 3: 6 values, expected 7"},
      {"2,0,0,0,0,0,9.8,1\n", "line 3: more than 7 values"},
      {"2,nan,0,0,0,0,9.8\n", "line 3: 'nan' is not a finite number"},
      {"2,0,0,1e999,0,0,9.8\n", "line 3: '1e999' is not a finite number"},
      {"2,0,,0,0,0,9.8\n", "line 3: '' is not a finite number"},
      {"1,0,0,0,0,0,9.8\n", "line 3: time 1.000000 s is not after the previous sample's"},
  };
  for (const auto& c : cases) {
    const std::string message = read_error(header + c.row);
    EXPECT_NE(message.find("bad.csv"), std::string::npos) << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.row << " -> " << message;
  }
  EXPECT_THROW(read_imu_csv("/nonexistent/imu.csv"), core::Error);
}

// A constant rate about one axis integrates to exactly that rate times the time.
TEST(GyroRotationTrack, ConstantRateIntegratesExactly) {
  std::vector<ImuSample> samples;
  const Eigen::Vector3d rate(0.0, 0.0, 0.3);
  for (int k = 0; k <= 200; ++k) samples.push_back({10.0 + 0.005 * k, rate, Eigen::Vector3d::Zero()});
  const Trajectory track = gyro_rotation_track(samples, Eigen::Quaterniond::Identity());
  ASSERT_EQ(track.size(), samples.size());
  EXPECT_TRUE(track.poses().front().T_world_lidar.isApprox(Eigen::Isometry3d::Identity()));
  const Eigen::AngleAxisd at_end(track.poses().back().T_world_lidar.linear());
  EXPECT_NEAR(at_end.angle(), 0.3 * 1.0, 1e-12);
  EXPECT_NEAR(at_end.axis().z(), 1.0, 1e-12);
  EXPECT_EQ(track.poses().back().T_world_lidar.translation(), Eigen::Vector3d::Zero());
  EXPECT_THROW(gyro_rotation_track({samples[0]}, Eigen::Quaterniond::Identity()), std::invalid_argument);
}

// An IMU mounted turned against the LIDAR measures the same motion in its own axes; with
// rotation_lidar_imu the track of the LIDAR is the same as from an IMU in the LIDAR's axes.
TEST(GyroRotationTrack, AnImuInOtherAxesGivesTheSameLidarRotation) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 0.5);
  const Eigen::Quaterniond q_lidar_imu(core::rotation_from_rpy(0.3, -1.2, 2.5));
  std::vector<ImuSample> in_lidar, in_imu;
  for (int k = 0; k <= 400; ++k) {
    const Eigen::Vector3d w = Eigen::Vector3d(0.3, -0.2, 0.5) + Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    in_lidar.push_back({0.0025 * k, w, Eigen::Vector3d::Zero()});
    in_imu.push_back({0.0025 * k, q_lidar_imu.inverse() * w, Eigen::Vector3d::Zero()});
  }
  const Trajectory a = gyro_rotation_track(in_lidar, Eigen::Quaterniond::Identity());
  const Trajectory b = gyro_rotation_track(in_imu, q_lidar_imu);
  for (std::size_t k = 0; k < a.size(); k += 50) {
    EXPECT_LT(core::rotation_error_rad(a.poses()[k].T_world_lidar, b.poses()[k].T_world_lidar), 1e-9) << k;
  }
  // Without the rotation the LIDAR's track is wrong (the test can fail).
  const Trajectory wrong = gyro_rotation_track(in_imu, Eigen::Quaterniond::Identity());
  EXPECT_GT(core::rotation_error_rad(a.poses().back().T_world_lidar, wrong.poses().back().T_world_lidar), 0.1);
}

}  // namespace
}  // namespace rgbdt::rgbdt_map
