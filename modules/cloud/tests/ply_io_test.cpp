// PLY reading (load_ply, load_cloud): files as PCL and CloudCompare write them load with
// every field; broken and hostile ones end in an error naming the file.
#include <gtest/gtest.h>
#include <pcl/io/ply_io.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "child_load.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/error.hpp"

using namespace rgbdt::cloud;
namespace fs = std::filesystem;
using rgbdt::cloud::test_support::kRefusedWithPath;

namespace {

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "ply_io";
  fs::create_directories(dir);
  return dir / name;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

int load_in_child(const fs::path& path, const std::string& part = "") {
  return rgbdt::cloud::test_support::load_in_child([](const std::string& p) { load_cloud(p); },
                                                   path, part);
}

Cloud sample_cloud() {
  Cloud c;
  for (int i = 0; i < 50; ++i) {
    PointXYZIRT p;
    p.x = 0.02f * i;
    p.y = -1.5f + 0.007f * i;
    p.z = 3.0f + 0.0003f * i;
    p.intensity = static_cast<float>(i % 11);
    p.ring = static_cast<std::uint16_t>(i / 5);
    p.t = 0.0005f * i;
    c.push_back(p);
  }
  return c;
}

// Binary files hold the floats exactly; PCL writes ASCII with fewer digits than a float
// needs, so those compare to within 4 units in the last place.
void expect_same(const Cloud& in, const LoadedCloud& out, bool exact) {
  EXPECT_TRUE(out.has_intensity && out.has_ring && out.has_t);
  ASSERT_EQ(out.cloud->size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    for (const auto member : {&PointXYZIRT::x, &PointXYZIRT::y, &PointXYZIRT::z,
                              &PointXYZIRT::intensity, &PointXYZIRT::t}) {
      if (exact) {
        EXPECT_EQ(out.cloud->at(i).*member, in[i].*member) << i;
      } else {
        EXPECT_FLOAT_EQ(out.cloud->at(i).*member, in[i].*member) << i;
      }
    }
    EXPECT_EQ(out.cloud->at(i).ring, in[i].ring) << i;
  }
}

template <typename T>
void append_be(std::string& s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (std::size_t k = sizeof(T); k-- > 0;) s += b[k];
}

}  // namespace

TEST(PlyIo, PclAsciiAndBinaryFilesRoundTripEveryField) {
  const Cloud in = sample_cloud();
  for (const bool binary : {false, true}) {
    const auto path = temp_file(binary ? "pcl_binary.ply" : "pcl_ascii.ply");
    ASSERT_EQ(pcl::io::savePLYFile(path.string(), in, binary), 0);
    SCOPED_TRACE(path.string());
    expect_same(in, load_ply(path.string()), binary);
    expect_same(in, load_cloud(path.string()), binary);
  }
}

TEST(PlyIo, CloudCompareScalarFieldsAndBigEndianLoad) {
  // CloudCompare writes scalar fields as "scalar_<Name>", and doubles for coordinates when
  // asked; here in big-endian order, with a face element after the vertices.
  std::string file =
      "ply\nformat binary_big_endian 1.0\ncomment Created by CloudCompare\nobj_info x\n"
      "element vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
      "property float scalar_Intensity\nproperty ushort scalar_Ring\nproperty float scalar_Time\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (int i = 0; i < 3; ++i) {
    append_be<double>(file, 1.0 + i);
    append_be<double>(file, -2.0 * i);
    append_be<double>(file, 0.5);
    append_be<float>(file, 10.0f * i);
    append_be<std::uint16_t>(file, static_cast<std::uint16_t>(7 + i));
    append_be<float>(file, 1000.0f + 0.25f * i);
  }
  file += std::string("\x03", 1);
  for (int i = 0; i < 3; ++i) append_be<std::int32_t>(file, i);
  const auto path = temp_file("cloudcompare.PLY");
  write_bytes(path, file);
  const LoadedCloud out = load_cloud(path.string());
  ASSERT_EQ(out.cloud->size(), 3u);
  EXPECT_TRUE(out.has_intensity && out.has_ring && out.has_t);
  EXPECT_EQ(out.cloud->at(2).x, 3.0f);
  EXPECT_EQ(out.cloud->at(2).y, -4.0f);
  EXPECT_EQ(out.cloud->at(1).intensity, 10.0f);
  EXPECT_EQ(out.cloud->at(2).ring, 9);
  // "time" is absolute: made relative to the earliest point.
  EXPECT_EQ(out.cloud->at(0).t, 0.0f);
  EXPECT_EQ(out.cloud->at(2).t, 0.5f);
}

TEST(PlyIo, AsciiXyzOnlyDropsNonFinitePoints) {
  const auto path = temp_file("xyz.ply");
  write_bytes(
      path,
      "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\n"
      "property float y\r\nproperty float z\r\nend_header\r\n1 2 3\r\nnan 0 0\r\n4 5 6\r\n");
  const LoadedCloud out = load_ply(path.string());
  EXPECT_FALSE(out.has_intensity || out.has_ring || out.has_t);
  ASSERT_EQ(out.cloud->size(), 2u);
  EXPECT_EQ(out.cloud->at(1).z, 6.0f);
}

TEST(PlyIoHostile, BrokenFilesAreRefusedNamingTheFile) {
  const std::string h3 =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\n";
  struct Case {
    const char* name;
    std::string bytes;
    const char* part;
  };
  const std::vector<Case> cases = {
      {"empty.ply", "", "empty"},
      {"not_ply.ply", "plx\nformat ascii 1.0\n", "expected 'ply'"},
      {"no_end.ply", "ply\nformat ascii 1.0\nelement vertex 1\n", "end_header"},
      {"bad_format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n",
       "binary_middle_endian"},
      {"no_format.ply", "ply\nelement vertex 0\nend_header\n", "format"},
      {"no_vertex.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n", "element vertex"},
      {"no_xyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
       "expected at least x y z"},
      {"bad_type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
       "'property float128 x'"},
      {"huge_count.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
       "property float y\nproperty float z\nend_header\n" +
           std::string(1200, '\0'),
       "48000000000 bytes"},
      {"ascii_huge_count.ply",
       "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
       "property float z\nend_header\n1 2 3\n",
       "4000000000"},
      {"short_ascii.ply", h3 + "end_header\n1.0 2.0 3.0\n\n\n\n\n\n\n",
       "holds 1 vertices, expected 2"},
      {"wrong_tokens.ply", h3 + "end_header\n1.0 2.0 3.0\n4.0 5.0\n",
       "(vertex 1) has 2 values, expected 3"},
      {"bad_number.ply", h3 + "end_header\n1 2 3\n4 5 zz\n", "property z: 'zz'"},
      {"ring_big.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
       "float z\n"
       "property uint ring\nend_header\n1 2 3 65535\n",
       "point 0: ring = 65535"},
      {"t_nan.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
       "float z\n"
       "property float t\nend_header\n1 2 3 nan\n",
       "point 0: t = nan"},
      {"cloud.xyz", "1 2 3\n", "expected .pcd or .ply"},
  };
  for (const auto& c : cases) {
    const auto path = temp_file(c.name);
    write_bytes(path, c.bytes);
    EXPECT_EQ(load_in_child(path, c.part), kRefusedWithPath) << c.name;
  }
}
