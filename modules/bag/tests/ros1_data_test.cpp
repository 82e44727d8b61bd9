// Real ROS 1 bags (../shared/data/art-bp-calib: a 16-ring Hesai LIDAR recorded with `rosbag
// record`, 3 poses of a board, 2 sweeps each): every PointCloud2 decodes from the ROS 1
// serialization and its points are plausible for the sensor.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"

namespace rgbdt::bag {
namespace {

namespace fs = std::filesystem;

fs::path scene_dir() {
  const fs::path dir = fs::path(RGBDT_SHARED_DATA_DIR) / "art-bp-calib" / "calib_data" / "scene";
  if (!fs::is_directory(dir)) ADD_FAILURE() << "missing real-data folder " << dir;
  return dir;
}

class BoardBag : public testing::TestWithParam<const char*> {};

TEST_P(BoardBag, PointCloud2DecodesWithPlausiblePoints) {
  const fs::path path = scene_dir() / (std::string(GetParam()) + "_short.bag");
  ASSERT_TRUE(fs::is_regular_file(path)) << "missing " << path;
  const auto reader = open_bag(path);
  const TopicInfo* topic = reader->find_topic("/lidar_points");
  ASSERT_NE(topic, nullptr);
  EXPECT_EQ(topic->type, "sensor_msgs/PointCloud2");
  EXPECT_EQ(serialization_of(*topic), Serialization::kRos1);
  EXPECT_EQ(topic->message_count, 2u);  // PROVENANCE.md: 2 sweeps per pose

  int clouds = 0;
  std::int64_t first_stamp_ns = 0;
  while (const auto message = reader->next()) {
    if (message->topic != topic) continue;
    const MessageContext context = context_of(*message);
    const PointCloud2 cloud = decode_point_cloud2(message->data, message->size, context);
    EXPECT_EQ(cloud.header.frame_id, "hesai_lidar");
    EXPECT_EQ(std::uint64_t{cloud.width} * cloud.height, 64000u);  // PROVENANCE.md
    EXPECT_GE(cloud.row_step, cloud.width * cloud.point_step);
    EXPECT_EQ(cloud.data.size(), std::size_t{cloud.row_step} * cloud.height);
    // The header stamp is near the recorder's log time (same machine, live driver).
    EXPECT_LT(std::abs(cloud.header.stamp.to_ns() - message->log_time_ns), 1000000000);
    if (clouds == 0) first_stamp_ns = cloud.header.stamp.to_ns();

    const CloudPoints points = extract_points(cloud, context);
    ASSERT_EQ(points.xyz.size(), 64000u);
    ASSERT_EQ(points.ring.size(), 64000u);
    ASSERT_EQ(points.intensity.size(), 64000u);
    EXPECT_EQ(points.time_field, "timestamp");
    std::size_t finite = 0;
    for (std::size_t i = 0; i < points.xyz.size(); ++i) {
      const auto& p = points.xyz[i];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
      ++finite;
      // A 16-channel Hesai ranges to ~150 m; its beams span +-15 deg, so |z| <= r * sin(15).
      const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      EXPECT_LT(r, 200.0) << "point " << i;
      EXPECT_LE(std::abs(p[2]), r * std::sin(16.0 * M_PI / 180.0) + 1e-3) << "point " << i;
      EXPECT_LT(points.ring[i], 16u) << "point " << i;
      EXPECT_TRUE(std::isfinite(points.intensity[i])) << "point " << i;
    }
    // PROVENANCE.md: ~62k of 64k points are finite.
    EXPECT_GT(finite, 55000u);
    EXPECT_LE(finite, 64000u);
    // One sweep of a 10 Hz LIDAR: its points' times span at most ~0.1 s, near the stamp.
    std::int64_t t_min = points.time_ns.front(), t_max = t_min;
    for (std::int64_t t : points.time_ns) {
      t_min = std::min(t_min, t);
      t_max = std::max(t_max, t);
    }
    EXPECT_LT(t_max - t_min, 150000000) << "time span of a sweep";
    EXPECT_LT(std::abs(t_min - cloud.header.stamp.to_ns()), 200000000);
    ++clouds;
  }
  EXPECT_EQ(clouds, 2);
  // PROVENANCE.md: the bags' stamps.
  const double stamp_s = first_stamp_ns * 1e-9;
  const double expected_s = std::string(GetParam()) == "mid"    ? 1777110074.67
                            : std::string(GetParam()) == "left" ? 1777110152.29
                                                                : 1777110184.39;
  EXPECT_NEAR(stamp_s, expected_s, 1.0);
}

INSTANTIATE_TEST_SUITE_P(Poses, BoardBag, testing::Values("left", "mid", "right"));

}  // namespace
}  // namespace rgbdt::bag
