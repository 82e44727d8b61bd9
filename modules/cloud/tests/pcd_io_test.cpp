#include <gtest/gtest.h>

#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "child_load.hpp"
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

// ---- Hostile and broken files: each must end in rgbdt::core::Error naming the file, never in
// a signal or an unbounded allocation (see child_load.hpp).

namespace {

using rgbdt::cloud::test_support::kLoaded;
using rgbdt::cloud::test_support::kRefusedWithPath;

int load_in_child(const fs::path& path, const std::string& part = "",
                  std::size_t cap_bytes = std::size_t{512} << 20) {
  return rgbdt::cloud::test_support::load_in_child([](const std::string& p) { load_pcd(p); }, path,
                                                   part, cap_bytes);
}

std::string header(const std::string& fields, const std::string& sizes, const std::string& types,
                   const std::string& counts, long width, long points, const std::string& data) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS " + fields + "\nSIZE " +
         sizes + "\nTYPE " + types + "\nCOUNT " + counts + "\nWIDTH " + std::to_string(width) +
         "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(points) + "\nDATA " +
         data + "\n";
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

/// Offset of the first byte after the "DATA ...\n" line.
std::size_t data_offset(const std::string& file) {
  const auto pos = file.find("\nDATA ");
  return file.find('\n', pos + 1) + 1;
}

std::uint32_t u32_at(const std::string& s, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, s.data() + at, 4);
  return v;
}

void put_u32(std::string& s, std::size_t at, std::uint32_t v) { std::memcpy(&s[at], &v, 4); }

/// A compressed PCD of the sample cloud, as PCL writes it.
std::string compressed_sample(const std::string& name) {
  const auto path = temp_file(name);
  save_pcd(path.string(), sample_cloud(), PcdFormat::kBinaryCompressed);
  return read_bytes(path);
}

}  // namespace

TEST(PcdIoHostile, EmptyFileIsRefusedNamingIt) {
  const auto path = temp_file("empty.pcd");
  write_bytes(path, "");
  EXPECT_EQ(load_in_child(path, "empty"), kRefusedWithPath);
}

TEST(PcdIoHostile, RandomBytesAreRefused) {
  std::mt19937 rng(28);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int k = 0; k < 5; ++k) {
    std::string bytes(4096, '\0');
    for (auto& c : bytes) c = static_cast<char>(byte(rng));
    const auto path = temp_file("random_" + std::to_string(k) + ".pcd");
    write_bytes(path, bytes);
    EXPECT_EQ(load_in_child(path), kRefusedWithPath) << "random file " << k;
  }
}

TEST(PcdIoHostile, CompressedSizeZeroIsRefused) {
  std::string file = compressed_sample("c0_src.pcd");
  put_u32(file, data_offset(file), 0);
  const auto path = temp_file("compressed_size_0.pcd");
  write_bytes(path, file);
  EXPECT_EQ(load_in_child(path, "compressed size 0"), kRefusedWithPath);
}

TEST(PcdIoHostile, CompressedSizeBeyondTheFileIsRefused) {
  std::string file = compressed_sample("cbig_src.pcd");
  put_u32(file, data_offset(file), 0x7fffffffu);
  const auto path = temp_file("compressed_size_big.pcd");
  write_bytes(path, file);
  EXPECT_EQ(load_in_child(path, "2147483647"), kRefusedWithPath);
}

TEST(PcdIoHostile, CompressedWithPointsInflatedFourTimesIsRefused) {
  // The case: PCL only warns "Data corruption?" and returns scrambled points.
  std::string file = compressed_sample("x4_src.pcd");
  const std::string h = file.substr(0, data_offset(file));
  std::string inflated = h;
  for (const std::string key : {"WIDTH 100\n", "POINTS 100\n"}) {
    const auto pos = inflated.find(key);
    ASSERT_NE(pos, std::string::npos) << key;
    inflated.replace(pos, key.size(), key.substr(0, key.find(' ')) + " 400\n");
  }
  const auto path = temp_file("inflated_x4.pcd");
  write_bytes(path, inflated + file.substr(h.size()));
  EXPECT_EQ(load_in_child(path, "400"), kRefusedWithPath);
  // With the uncompressed size inflated to match the header, the data still decodes short.
  std::string both = inflated + file.substr(h.size());
  const std::size_t at = inflated.size() + 4;
  put_u32(both, at, u32_at(both, at) * 4);
  write_bytes(path, both);
  EXPECT_EQ(load_in_child(path), kRefusedWithPath);
}

TEST(PcdIoHostile, HugeUncompressedClaimIsRefusedBeforeAllocating) {
  // 600 kB of data that claims 4 GB - 1 uncompressed (POINTS matching): refused from the
  // header, under a 64 MB address-space cap.
  const std::size_t points = 0xffffffffu / 16;
  std::string file = header("x y z t", "4 4 4 4", "F F F F", "1 1 1 1", static_cast<long>(points),
                            static_cast<long>(points), "binary_compressed");
  const std::uint32_t compressed = 600000;
  std::string sizes(8, '\0');
  put_u32(sizes, 0, compressed);
  put_u32(sizes, 4, static_cast<std::uint32_t>(points * 16));
  file += sizes + std::string(compressed, '\x1f');
  const auto path = temp_file("huge_claim.pcd");
  write_bytes(path, file);
  EXPECT_EQ(load_in_child(path, "uncompressed", std::size_t{64} << 20), kRefusedWithPath);
}

TEST(PcdIoHostile, BinaryShorterThanPointsSayIsRefused) {
  const auto path = temp_file("binary_short.pcd");
  std::string file = header("x y z", "4 4 4", "F F F", "1 1 1", 1000, 1000, "binary");
  file += std::string(12 * 999, '\0');
  write_bytes(path, file);
  EXPECT_EQ(load_in_child(path, "12000"), kRefusedWithPath);
}

TEST(PcdIoHostile, AsciiPointsBeyondTheFileAreRefused) {
  const auto path = temp_file("ascii_too_many.pcd");
  write_bytes(path, header("x y z", "4 4 4", "F F F", "1 1 1", 2000000000, 2000000000, "ascii") +
                        "1 2 3\n4 5 6\n");
  EXPECT_EQ(load_in_child(path, "2000000000", std::size_t{64} << 20), kRefusedWithPath);
}

TEST(PcdIoHostile, AsciiWithFewerPointsThanPromisedIsRefused) {
  const auto path = temp_file("ascii_short.pcd");
  write_bytes(path, header("x y z", "4 4 4", "F F F", "1 1 1", 3, 3, "ascii") +
                        "1.0 2.0 3.0\n4.0 5.0 6.0\n");
  EXPECT_EQ(load_in_child(path, "holds 2 points, expected POINTS 3"), kRefusedWithPath);
  // A value that is not a number is named with its line and field.
  write_bytes(path, header("x y z", "4 4 4", "F F F", "1 1 1", 2, 2, "ascii") +
                        "1.0 2.0 3.0\n4.0 5x 6.0\n");
  EXPECT_EQ(load_in_child(path, "line 13 (point 1), field y: '5x'"), kRefusedWithPath);
}

TEST(PcdIoHostile, HeaderCountMismatchIsRefused) {
  const auto path = temp_file("mismatch.pcd");
  write_bytes(path, header("x y z t", "4 4 4", "F F F F", "1 1 1 1", 1, 1, "ascii") + "1 2 3 4\n");
  EXPECT_EQ(load_in_child(path, "SIZE"), kRefusedWithPath);
  write_bytes(path,
              header("x y z", "4 4 3", "F F F", "1 1 1", 1, 1, "binary") + std::string(11, '\0'));
  EXPECT_EQ(load_in_child(path, "SIZE '3'"), kRefusedWithPath);
  write_bytes(path,
              header("x y z", "4 4 4", "F F F", "1 1 1", 2, 3, "ascii") + "1 2 3\n4 5 6\n7 8 9\n");
  EXPECT_EQ(load_in_child(path, "WIDTH"), kRefusedWithPath);
}

TEST(PcdIoHostile, TimeNotFiniteOrFarOffIsRefusedNamingPointAndValue) {
  const auto path = temp_file("t_bad.pcd");
  const std::string h = header("x y z t", "4 4 4 4", "F F F F", "1 1 1 1", 3, 3, "ascii");
  write_bytes(path, h + "1 2 3 0\n1 2 3 nan\n1 2 3 0.1\n");
  EXPECT_EQ(load_in_child(path, "point 1: t = nan"), kRefusedWithPath);
  write_bytes(path, h + "1 2 3 0\n1 2 3 0.05\n1 2 3 1e30\n");
  EXPECT_EQ(load_in_child(path, "point 2: t = 1e+30"), kRefusedWithPath);
  // Absolute times (field "timestamp") are checked after subtracting the earliest one.
  const std::string ha = header("x y z timestamp", "4 4 4 8", "F F F F", "1 1 1 1", 2, 2, "ascii");
  write_bytes(path, ha + "1 2 3 1700000000.0\n1 2 3 1700009000.0\n");
  EXPECT_EQ(load_in_child(path, "9000"), kRefusedWithPath);
}

TEST(PcdIoHostile, DoubleCoordinateBeyondFloatRangeIsRefused) {
  const auto path = temp_file("x_1e300.pcd");
  write_bytes(path,
              header("x y z", "8 4 4", "F F F", "1 1 1", 2, 2, "ascii") + "1 2 3\n1e300 2 3\n");
  EXPECT_EQ(load_in_child(path, "point 1: x = 1e+300"), kRefusedWithPath);
}

TEST(PcdIoHostile, RingOutOfRangeIsRefused) {
  Cloud c = sample_cloud();
  c[42].ring = 65535;
  const auto path = temp_file("ring.pcd");
  save_pcd(path.string(), c, PcdFormat::kBinary);
  EXPECT_EQ(load_in_child(path, "point 42: ring = 65535"), kRefusedWithPath);
}

TEST(PcdIoHostile, ValidFilesStillLoadInTheChild) {
  // The harness itself: a valid file is reported as loaded, so the codes above are meaningful.
  const auto path = temp_file("valid.pcd");
  save_pcd(path.string(), sample_cloud(), PcdFormat::kBinaryCompressed);
  EXPECT_EQ(load_in_child(path), kLoaded);
}

TEST(PcdIo, RealFilesLoadWithThePointCountPclGives) {
  // Every PCD of the shared real data (ascii, binary and binary_compressed, with absolute
  // "timestamp" fields and rings) loads, point for point as PCL reads it.
  const fs::path data(RGBDT_SHARED_DATA_DIR);
  std::vector<fs::path> files;
  for (const char* dir : {"discocal", "pjlab-sensorscalibration"}) {
    if (!fs::exists(data / dir)) {
      ADD_FAILURE() << "real data folder missing: " << data / dir
                    << " (CI keeps ../shared beside the checkout)";
      continue;
    }
    for (const auto& e : fs::recursive_directory_iterator(data / dir)) {
      if (e.path().extension() == ".pcd") files.push_back(e.path());
    }
  }
  EXPECT_GE(files.size(), 19u);
  for (const auto& path : files) {
    if (!fs::exists(path)) {
      ADD_FAILURE() << "real data file missing: " << path
                    << " (CI keeps ../shared beside the checkout)";
      continue;
    }
    pcl::PCLPointCloud2 msg;
    ASSERT_EQ(pcl::PCDReader().read(path.string(), msg), 0) << path;
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::fromPCLPointCloud2(msg, xyz);
    std::size_t finite = 0;
    for (const auto& p : xyz)
      finite += std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    const LoadedCloud out = load_pcd(path.string());
    EXPECT_EQ(out.cloud->size(), finite) << path;
    EXPECT_GT(finite, 50000u) << path;
    // The same coordinates in the same order.
    std::size_t k = 0;
    for (const auto& p : xyz) {
      if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))) continue;
      if (k >= out.cloud->size()) break;
      const auto& q = out.cloud->at(k++);
      if (p.x != q.x || p.y != q.y || p.z != q.z) {
        ADD_FAILURE() << path << ": point " << k - 1 << " differs from PCL's";
        break;
      }
    }
  }
}
