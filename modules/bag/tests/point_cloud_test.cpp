// PointCloud2 point extraction: the per-point time and ring fields of the common LIDAR
// drivers, byte order, padded rows, and layouts that must be rejected.
#include <gtest/gtest.h>

#include <cmath>

#include "cdr_writer.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::bag {
namespace {

const MessageContext kContext{"/points", 3, 0};

template <typename T>
void store(PointCloud2& cloud, std::size_t point, std::uint32_t offset, T value) {
  std::uint8_t raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  if (cloud.is_bigendian) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
  }
  std::memcpy(cloud.data.data() + point * cloud.point_step + offset, raw, sizeof(T));
}

PointCloud2 empty_cloud(std::uint32_t n, std::uint32_t point_step, std::vector<PointField> fields) {
  PointCloud2 cloud;
  cloud.header.stamp = {1700000000, 500000000};
  cloud.height = 1;
  cloud.width = n;
  cloud.fields = std::move(fields);
  cloud.point_step = point_step;
  cloud.row_step = point_step * n;
  cloud.data.assign(std::size_t{point_step} * n, 0);
  return cloud;
}

std::string error_of(const PointCloud2& cloud) {
  try {
    extract_points(cloud, kContext);
  } catch (const core::Error& e) {
    return e.what();
  }
  return "(no error)";
}

constexpr std::int64_t kStampNs = 1700000000500000000;

TEST(PointCloudExtract, VelodyneTimeIsSecondsAfterStamp) {
  // Through CDR and back, as from a bag.
  const auto bytes = test::encode(test::velodyne_cloud(20, 1700000000, 500000000));
  const PointCloud2 cloud = decode_point_cloud2(bytes.data(), bytes.size(), kContext);
  const CloudPoints points = extract_points(cloud, kContext);
  ASSERT_EQ(points.xyz.size(), 20u);
  ASSERT_EQ(points.intensity.size(), 20u);
  ASSERT_EQ(points.ring.size(), 20u);
  ASSERT_EQ(points.time_ns.size(), 20u);
  EXPECT_EQ(points.time_field, "time");
  for (std::size_t i = 0; i < 20; ++i) {
    EXPECT_EQ(points.xyz[i][0], double(i));
    EXPECT_EQ(points.xyz[i][1], -2.0 * double(i));
    EXPECT_EQ(points.xyz[i][2], 0.5 * double(i));
    EXPECT_EQ(points.intensity[i], 10.0f * float(i));
    EXPECT_EQ(points.ring[i], i % 16);
    EXPECT_NEAR(double(points.time_ns[i] - kStampNs), 1e5 * double(i), 1.0) << i;
  }
}

TEST(PointCloudExtract, OusterTIsNanosecondsAfterStamp) {
  PointCloud2 cloud = empty_cloud(3, 48,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"intensity", 16, PointField::kFloat32, 1},
                                   {"t", 20, PointField::kUint32, 1},
                                   {"reflectivity", 24, PointField::kUint16, 1},
                                   {"ring", 26, PointField::kUint16, 1},
                                   {"ambient", 28, PointField::kUint16, 1},
                                   {"range", 32, PointField::kUint32, 1}});
  for (std::uint32_t i = 0; i < 3; ++i) {
    store<float>(cloud, i, 0, 1.5f);
    store<std::uint32_t>(cloud, i, 20, 97656u * i);
    store<std::uint16_t>(cloud, i, 26, std::uint16_t(127 - i));
  }
  const CloudPoints points = extract_points(cloud, kContext);
  EXPECT_EQ(points.time_field, "t");
  EXPECT_EQ(points.time_ns,
            (std::vector<std::int64_t>{kStampNs, kStampNs + 97656, kStampNs + 2 * 97656}));
  EXPECT_EQ(points.ring, (std::vector<std::uint16_t>{127, 126, 125}));
  EXPECT_EQ(points.xyz[2][0], 1.5);
}

TEST(PointCloudExtract, FloatTIsSecondsAfterStamp) {
  // rgbdt's own PCD field: float32 seconds.
  PointCloud2 cloud = empty_cloud(3, 16,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"t", 12, PointField::kFloat32, 1}});
  for (std::uint32_t i = 0; i < 3; ++i) store<float>(cloud, i, 12, 0.25f * i);
  const CloudPoints points = extract_points(cloud, kContext);
  EXPECT_EQ(points.time_field, "t");
  EXPECT_EQ(points.time_ns,
            (std::vector<std::int64_t>{kStampNs, kStampNs + 250000000, kStampNs + 500000000}));
}

TEST(PointCloudExtract, SignedIntegerTIsRejected) {
  PointCloud2 cloud = empty_cloud(1, 16,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"t", 12, PointField::kInt32, 1}});
  EXPECT_NE(error_of(cloud).find("field 't'"), std::string::npos) << error_of(cloud);
}

TEST(PointCloudExtract, LivoxTimestampIsAbsoluteNanosecondsAndLineIsRing) {
  PointCloud2 cloud = empty_cloud(2, 26,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"intensity", 12, PointField::kFloat32, 1},
                                   {"tag", 16, PointField::kUint8, 1},
                                   {"line", 17, PointField::kUint8, 1},
                                   {"timestamp", 18, PointField::kFloat64, 1}});
  store<double>(cloud, 0, 18, double(kStampNs));
  store<double>(cloud, 1, 18, double(kStampNs) + 4096.0);
  store<std::uint8_t>(cloud, 1, 17, 5);
  const CloudPoints points = extract_points(cloud, kContext);
  EXPECT_EQ(points.time_field, "timestamp");
  EXPECT_EQ(points.time_ns[0], kStampNs);
  EXPECT_EQ(points.time_ns[1], kStampNs + 4096);
  EXPECT_EQ(points.ring, (std::vector<std::uint16_t>{0, 5}));
}

TEST(PointCloudExtract, LivoxOffsetTimeIsNanosecondsAfterStamp) {
  PointCloud2 cloud = empty_cloud(2, 16,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"offset_time", 12, PointField::kUint32, 1}});
  store<std::uint32_t>(cloud, 1, 12, 100000u);
  const CloudPoints points = extract_points(cloud, kContext);
  EXPECT_EQ(points.time_field, "offset_time");
  EXPECT_EQ(points.time_ns, (std::vector<std::int64_t>{kStampNs, kStampNs + 100000}));
  EXPECT_TRUE(points.intensity.empty());
  EXPECT_TRUE(points.ring.empty());
}

TEST(PointCloudExtract, HesaiTimestampIsAbsoluteSeconds) {
  PointCloud2 cloud = empty_cloud(2, 32,
                                  {{"x", 0, PointField::kFloat32, 1},
                                   {"y", 4, PointField::kFloat32, 1},
                                   {"z", 8, PointField::kFloat32, 1},
                                   {"intensity", 12, PointField::kFloat32, 1},
                                   {"timestamp", 16, PointField::kFloat64, 1},
                                   {"ring", 24, PointField::kUint16, 1}});
  store<double>(cloud, 0, 16, 1700000000.5);
  store<double>(cloud, 1, 16, 1700000000.5625);
  CloudPoints points = extract_points(cloud, kContext);
  // A double holds seconds since 1970 to about 240 ns.
  EXPECT_NEAR(double(points.time_ns[0] - kStampNs), 0.0, 500.0);
  EXPECT_NEAR(double(points.time_ns[1] - kStampNs), 62500000.0, 500.0);

  // A clock far from the stamp needs the unit spelt out.
  store<double>(cloud, 0, 16, 3600.0);
  store<double>(cloud, 1, 16, 3600.25);
  PointExtractOptions options;
  options.float64_timestamp_unit = TimestampUnit::kSeconds;
  points = extract_points(cloud, kContext, options);
  EXPECT_EQ(points.time_ns[0], 3600000000000);
  EXPECT_EQ(points.time_ns[1], 3600250000000);
}

TEST(PointCloudExtract, BigEndianFloat64AndPaddedRows) {
  PointCloud2 cloud;
  cloud.header.stamp = {10, 0};
  cloud.is_bigendian = true;
  cloud.height = 2;
  cloud.width = 2;
  cloud.fields = {{"x", 0, PointField::kFloat64, 1},
                  {"y", 8, PointField::kFloat64, 1},
                  {"z", 16, PointField::kFloat64, 1},
                  {"intensity", 24, PointField::kUint16, 1},
                  {"ring", 26, PointField::kInt8, 1}};
  cloud.point_step = 27;
  cloud.row_step = 60;  // 6 bytes of padding after each row of 2 x 27
  cloud.data.assign(cloud.row_step * 2, 0xEE);
  for (std::size_t row = 0; row < 2; ++row) {
    for (std::size_t col = 0; col < 2; ++col) {
      std::uint8_t* p = cloud.data.data() + row * cloud.row_step + col * cloud.point_step;
      const double v[3] = {double(row) + 0.25, double(col) - 0.5, 1e-3};
      for (int k = 0; k < 3; ++k) {
        std::uint8_t raw[8];
        std::memcpy(raw, &v[k], 8);
        for (int b = 0; b < 8; ++b) p[8 * k + b] = raw[7 - b];
      }
      p[24] = 0x01;  // intensity 0x0102 = 258, big endian
      p[25] = 0x02;
      p[26] = std::uint8_t(row * 2 + col);
    }
  }
  const CloudPoints points = extract_points(cloud, kContext);
  ASSERT_EQ(points.xyz.size(), 4u);
  EXPECT_EQ(points.xyz[3][0], 1.25);
  EXPECT_EQ(points.xyz[3][1], 0.5);
  EXPECT_EQ(points.xyz[2][1], -0.5);
  EXPECT_EQ(points.xyz[1][2], 1e-3);
  EXPECT_EQ(points.intensity[3], 258.0f);
  EXPECT_EQ(points.ring, (std::vector<std::uint16_t>{0, 1, 2, 3}));
  EXPECT_TRUE(points.time_ns.empty());
  EXPECT_EQ(points.time_field, "");
}

TEST(PointCloudExtract, FieldPastPointStepThrows) {
  PointCloud2 cloud = test::velodyne_cloud(4, 1, 0);
  cloud.point_step = 20;  // time ends at byte 22
  cloud.row_step = 80;
  const std::string message = error_of(cloud);
  EXPECT_NE(message.find("field 'time'"), std::string::npos) << message;
  EXPECT_NE(message.find("past point_step 20"), std::string::npos) << message;
  EXPECT_NE(message.find("topic /points, message 3"), std::string::npos) << message;

  cloud = test::velodyne_cloud(4, 1, 0);
  cloud.fields[0].count = 9;  // 9 floats from offset 0: 36 bytes > 32
  EXPECT_NE(error_of(cloud).find("field 'x'"), std::string::npos);
}

TEST(PointCloudExtract, ShortDataThrows) {
  PointCloud2 cloud = test::velodyne_cloud(4, 1, 0);
  cloud.data.resize(cloud.data.size() - 1);
  const std::string message = error_of(cloud);
  EXPECT_NE(message.find("data has 127 bytes"), std::string::npos) << message;

  // Sizes from hostile headers must not wrap around.
  cloud = test::velodyne_cloud(4, 1, 0);
  cloud.width = 0xFFFFFFFFu;
  EXPECT_NE(error_of(cloud).find("data has 128 bytes"), std::string::npos);
  cloud.height = 0xFFFFFFFFu;
  cloud.row_step = 0xFFFFFFFFu;
  EXPECT_NE(error_of(cloud), "(no error)");
}

TEST(PointCloudExtract, RowStepShorterThanRowThrows) {
  PointCloud2 cloud = test::velodyne_cloud(4, 1, 0);
  cloud.width = 2;
  cloud.height = 2;
  cloud.row_step = 32;
  EXPECT_NE(error_of(cloud).find("row_step 32 is less than"), std::string::npos);
}

TEST(PointCloudExtract, WrongDatatypesThrow) {
  PointCloud2 cloud = test::velodyne_cloud(2, 1, 0);
  cloud.fields[0].datatype = PointField::kInt32;
  EXPECT_NE(error_of(cloud).find("field 'x' is INT32, expected FLOAT32 or FLOAT64"),
            std::string::npos);

  cloud = test::velodyne_cloud(2, 1, 0);
  cloud.fields[4].datatype = PointField::kFloat32;  // ring
  EXPECT_NE(error_of(cloud).find("field 'ring' is FLOAT32"), std::string::npos);

  cloud = test::velodyne_cloud(2, 1, 0);
  cloud.fields[2].datatype = 11;
  EXPECT_NE(error_of(cloud).find("field 'z' has datatype 11"), std::string::npos);

  cloud = test::velodyne_cloud(2, 1, 0);
  cloud.fields.erase(cloud.fields.begin() + 1);
  EXPECT_NE(error_of(cloud).find("has no field 'y'"), std::string::npos);
}

TEST(PointCloudExtract, NonFiniteTimeThrows) {
  PointCloud2 cloud = test::velodyne_cloud(2, 1, 0);
  const float nan = std::nanf("");
  std::memcpy(cloud.data.data() + 32 + 18, &nan, 4);
  EXPECT_NE(error_of(cloud).find("point 1 has time that is not a finite time"), std::string::npos);
}

}  // namespace
}  // namespace rgbdt::bag
