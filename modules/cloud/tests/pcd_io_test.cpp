#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/error.hpp"

using namespace rgbdt::cloud;
namespace fs = std::filesystem;

namespace {
fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "pcd_io";
  fs::create_directories(dir);
  return dir / name;
}

Cloud sample_cloud() {
  Cloud c;
  for (int i = 0; i < 100; ++i) {
    PointXYZIRT p;
    p.x = 0.01f * i;
    p.y = -0.5f + 0.003f * i;
    p.z = 4.0f + 0.0001f * i;
    p.intensity = static_cast<float>(i % 7);
    p.ring = static_cast<std::uint16_t>(i / 10);
    p.t = 0.00025f * i;
    c.push_back(p);
  }
  return c;
}
}  // namespace

TEST(PcdIo, EveryFormatRoundTripsAllFields) {
  const Cloud in = sample_cloud();
  for (auto format : {PcdFormat::kAscii, PcdFormat::kBinary, PcdFormat::kBinaryCompressed}) {
    const auto path = temp_file("roundtrip_" + std::to_string(static_cast<int>(format)) + ".pcd");
    save_pcd(path.string(), in, format);
    const LoadedCloud out = load_pcd(path.string());
    EXPECT_TRUE(out.has_intensity && out.has_ring && out.has_t);
    ASSERT_EQ(out.cloud->size(), in.size());
    for (size_t i = 0; i < in.size(); ++i) {
      EXPECT_FLOAT_EQ(out.cloud->at(i).x, in[i].x);
      EXPECT_FLOAT_EQ(out.cloud->at(i).z, in[i].z);
      EXPECT_EQ(out.cloud->at(i).ring, in[i].ring);
      EXPECT_FLOAT_EQ(out.cloud->at(i).t, in[i].t);
      EXPECT_FLOAT_EQ(out.cloud->at(i).intensity, in[i].intensity);
    }
  }
}

TEST(PcdIo, XyzOnlyFileLoadsAndSaysWhatIsMissing) {
  const auto path = temp_file("xyz.pcd");
  std::ofstream(path) << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                         "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
                         "1 2 3\nnan nan nan\n4 5 6\n";
  const LoadedCloud out = load_pcd(path.string());
  EXPECT_FALSE(out.has_intensity);
  EXPECT_FALSE(out.has_ring);
  EXPECT_FALSE(out.has_t);
  ASSERT_EQ(out.cloud->size(), 2u);  // the NaN point is dropped
  EXPECT_FLOAT_EQ(out.cloud->at(1).y, 5.0f);
}

TEST(PcdIo, MissingFileAndMissingXyzAreNamed) {
  try {
    load_pcd("/nonexistent/a.pcd");
    FAIL();
  } catch (const rgbdt::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/a.pcd"), std::string::npos);
  }
  const auto path = temp_file("noxyz.pcd");
  std::ofstream(path) << "# .PCD v0.7\nVERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\n"
                         "WIDTH 1\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2\n";
  try {
    load_pcd(path.string());
    FAIL();
  } catch (const rgbdt::core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("noxyz.pcd"), std::string::npos) << what;
    EXPECT_NE(what.find("x y z"), std::string::npos) << what;
  }
}

TEST(PcdIo, RealBinaryCompressedFileWithRingLoads) {
  const fs::path path = fs::path(RGBDT_SHARED_DATA_DIR) /
                        "pjlab-sensorscalibration/lidar2camera/joint_calib/tool/LidarCircleDetect/data";
  if (!fs::exists(path)) {
    FAIL() << "real data folder missing: " << path << " (CI keeps ../shared beside the checkout)";
  }
  fs::path first;
  for (const auto& e : fs::directory_iterator(path)) {
    if (e.path().extension() == ".pcd" && (first.empty() || e.path() < first)) first = e.path();
  }
  ASSERT_FALSE(first.empty()) << "no .pcd in " << path;
  const LoadedCloud out = load_pcd(first.string());
  EXPECT_TRUE(out.has_ring);
  EXPECT_GT(out.cloud->size(), 1000u);
  int max_ring = 0;
  for (const auto& p : *out.cloud) max_ring = std::max<int>(max_ring, p.ring);
  EXPECT_GT(max_ring, 10);
  EXPECT_LT(max_ring, 64);
}
