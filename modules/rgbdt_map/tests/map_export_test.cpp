#include <gtest/gtest.h>

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <sys/resource.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>

#include "rgbdt/core/error.hpp"
#include "rgbdt/rgbdt_map/export.hpp"
#include "rgbdt/rgbdt_map/thermal_octree.hpp"
#include "rgbdt/rgbdt_map/voxel_map.hpp"

using namespace rgbdt::rgbdt_map;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" /
                       (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

RgbColors colors_of(const std::vector<std::array<std::uint8_t, 3>>& rgb, const std::vector<ColorStatus>& status) {
  RgbColors c;
  c.rgb = rgb;
  c.status = status;
  return c;
}

Temperatures temps_of(const std::vector<float>& k, const std::vector<ColorStatus>& status) {
  Temperatures t;
  t.temperature_k = k;
  t.status = status;
  return t;
}

std::vector<MapPoint> sample_points() {
  std::vector<MapPoint> points;
  for (int i = 0; i < 50; ++i) {
    MapPoint p;
    p.position_m = Eigen::Vector3f(0.1f * i, -0.05f * i, 0.3f + 0.01f * i);
    p.rgb = {static_cast<std::uint8_t>(i * 5), static_cast<std::uint8_t>(255 - i), 7};
    p.has_rgb = i % 7 != 0;
    p.temperature_k = i % 5 == 0 ? std::numeric_limits<float>::quiet_NaN() : 280.0f + 0.37f * i;
    points.push_back(p);
  }
  return points;
}

}  // namespace

TEST(VoxelMap, AveragesPositionColourAndTemperaturePerVoxel) {
  VoxelMap map({0.1});
  const int day = map.add_thermal_layer("day");
  const std::vector<Eigen::Vector3f> pts = {{0.01f, 0.01f, 0.01f}, {0.05f, 0.03f, 0.09f}, {0.55f, 0.0f, 0.0f}};
  const auto ok = ColorStatus::kColored;
  const RgbColors rgb = colors_of({{10, 20, 30}, {30, 40, 50}, {0, 0, 0}}, {ok, ok, ColorStatus::kOccluded});
  const Temperatures t = temps_of({300.0f, 302.0f, NAN}, {ok, ok, ColorStatus::kOutsideImage});
  map.insert(pts, &rgb, &t, day, 5.0);
  ASSERT_EQ(map.size(), 2u);
  const Voxel& v = map.voxels().at(map.key_of(pts[0]));
  EXPECT_EQ(v.count, 2u);
  EXPECT_EQ(v.color_count, 2u);
  EXPECT_TRUE(v.mean_position_m.isApprox(Eigen::Vector3f(0.03f, 0.02f, 0.05f)));
  EXPECT_TRUE(v.mean_rgb.isApprox(Eigen::Vector3f(20, 30, 40)));
  EXPECT_FLOAT_EQ(map.thermal_layer(day).at(map.key_of(pts[0])).mean_k, 301.0f);
  // The occluded point adds geometry but no colour: it is not painted black.
  const Voxel& lone = map.voxels().at(map.key_of(pts[2]));
  EXPECT_EQ(lone.count, 1u);
  EXPECT_EQ(lone.color_count, 0u);
  EXPECT_EQ(map.thermal_layer(day).count(map.key_of(pts[2])), 0u);
  for (const MapPoint& p : map.points(day)) {
    if (p.count == 1) {
      EXPECT_FALSE(p.has_rgb);
      EXPECT_TRUE(std::isnan(p.temperature_k));
    }
  }
  // Negative coordinates fall in their own voxels (floor, not truncation).
  EXPECT_NE(map.key_of({-0.01f, 0.0f, 0.0f}), map.key_of({0.01f, 0.0f, 0.0f}));
  EXPECT_THROW(map.insert(pts, &rgb, &t, 3, 0.0), std::invalid_argument);
  EXPECT_THROW(VoxelMap({0.0}), std::invalid_argument);
}

TEST(VoxelMap, FusesSessionsWithOneThermalLayerEach) {
  VoxelMap map({0.1});
  const int day = map.add_thermal_layer("day");
  const int night = map.add_thermal_layer("night");
  const std::vector<Eigen::Vector3f> pts = {{1.0f, 1.0f, 0.0f}};
  const auto ok = ColorStatus::kColored;
  const RgbColors rgb = colors_of({{200, 100, 0}}, {ok});
  const Temperatures warm = temps_of({310.0f}, {ok});
  const Temperatures cold = temps_of({285.0f}, {ok});
  map.insert(pts, &rgb, &warm, day, 1.0);
  map.insert(pts, nullptr, &cold, night, 50000.0);
  ASSERT_EQ(map.size(), 1u);
  EXPECT_EQ(map.voxels().begin()->second.count, 2u);
  EXPECT_EQ(map.voxels().begin()->second.last_time_s, 50000.0);
  EXPECT_FLOAT_EQ(map.points(day)[0].temperature_k, 310.0f);
  EXPECT_FLOAT_EQ(map.points(night)[0].temperature_k, 285.0f);
  EXPECT_EQ(map.thermal_layer_name(night), "night");
}

TEST(Export, PlyWriteThenReadRoundTrips) {
  const auto dir = temp_dir();
  const auto points = sample_points();
  write_ply((dir / "map.ply").string(), points, {1, 2, 3});
  // Header as CloudCompare expects it.
  std::ifstream in(dir / "map.ply", std::ios::binary);
  std::string header((std::istreambuf_iterator<char>(in)), {});
  header = header.substr(0, header.find("end_header"));
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("element vertex 50"), std::string::npos);
  EXPECT_NE(header.find("property float temperature"), std::string::npos);
  const auto back = read_ply((dir / "map.ply").string());
  ASSERT_EQ(back.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(back[i].position_m, points[i].position_m);
    const std::array<std::uint8_t, 3> want = points[i].has_rgb ? points[i].rgb : std::array<std::uint8_t, 3>{1, 2, 3};
    EXPECT_EQ(back[i].rgb, want);
    if (std::isnan(points[i].temperature_k)) {
      EXPECT_TRUE(std::isnan(back[i].temperature_k));
    } else {
      EXPECT_EQ(back[i].temperature_k, points[i].temperature_k);
    }
  }
  EXPECT_THROW(read_ply((dir / "missing.ply").string()), rgbdt::core::Error);
  std::ofstream(dir / "bad.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
  EXPECT_THROW(read_ply((dir / "bad.ply").string()), rgbdt::core::Error);
}

TEST(Export, PcdWriteThenReadRoundTrips) {
  const auto dir = temp_dir();
  const auto points = sample_points();
  write_pcd((dir / "map.pcd").string(), points);
  const auto back = read_map_pcd((dir / "map.pcd").string());
  ASSERT_EQ(back.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(back[i].position_m, points[i].position_m);
    if (points[i].has_rgb) {
      EXPECT_EQ(back[i].rgb, points[i].rgb);
    }
    EXPECT_EQ(std::isnan(back[i].temperature_k), std::isnan(points[i].temperature_k));
    if (!std::isnan(points[i].temperature_k)) {
      EXPECT_EQ(back[i].temperature_k, points[i].temperature_k);
    }
  }
}

TEST(Export, OccupancyTreeFromRaysKnowsFreeSpaceAndReadsBack) {
  const auto dir = temp_dir();
  OccupancyMapBuilder builder({0.05});
  // A wall at x = 4 m seen from the origin.
  std::vector<Eigen::Vector3f> wall;
  for (float y = -1.0f; y <= 1.0f; y += 0.02f) {
    for (float z = -0.5f; z <= 0.5f; z += 0.02f) wall.emplace_back(4.0f, y, z);
  }
  builder.insert_scan(wall, Eigen::Vector3d::Zero());
  builder.write_bt((dir / "map.bt").string());
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary((dir / "map.bt").string()));
  EXPECT_DOUBLE_EQ(tree.getResolution(), 0.05);
  const auto* on_wall = tree.search(4.0, 0.1, 0.1);
  ASSERT_NE(on_wall, nullptr);
  EXPECT_TRUE(tree.isNodeOccupied(on_wall));
  // Between the sensor and the wall the rays cleared the space...
  const auto* between = tree.search(2.0, 0.1, 0.1);
  ASSERT_NE(between, nullptr);
  EXPECT_FALSE(tree.isNodeOccupied(between));
  // ...and behind the wall nothing is known.
  EXPECT_EQ(tree.search(5.0, 0.1, 0.1), nullptr);
}

TEST(Export, PointsBeyondTheFreeSpaceRangeAreOccupiedWithoutCarving) {
  OccupancyOptions options;
  options.max_free_range_m = 3.0;
  OccupancyMapBuilder builder(options);
  std::vector<Eigen::Vector3f> wall;
  for (float y = -0.5f; y <= 0.5f; y += 0.02f) wall.emplace_back(4.0f, y, 0.0f);
  builder.insert_scan(wall, Eigen::Vector3d::Zero());
  octomap::OcTree& tree = builder.tree();
  const auto* on_wall = tree.search(4.0, 0.01, 0.01);
  ASSERT_NE(on_wall, nullptr);
  EXPECT_TRUE(tree.isNodeOccupied(on_wall));
  const auto* near = tree.search(2.0, 0.01, 0.01);
  ASSERT_NE(near, nullptr);
  EXPECT_FALSE(tree.isNodeOccupied(near));
  EXPECT_EQ(tree.search(3.5, 0.01, 0.01), nullptr);  // beyond the carving range: unknown
}

// A tilt's rays start where the sensor was when each point was measured: two points on
// a wall at x = 4 m seen from y = -1 and y = +1 carve their own rays, and nothing between.
TEST(Export, PerPointOriginsCastEachRayFromWhereTheSensorWas) {
  OccupancyOptions options;
  options.free_space_cell_m = 0.0;  // leaf by leaf, so the free cells are exactly the rays'
  OccupancyMapBuilder builder(options);
  const std::vector<Eigen::Vector3f> points = {{4.0f, -1.0f, 0.0f}, {4.0f, 1.0f, 0.0f}};
  const std::vector<Eigen::Vector3f> origins = {{0.0f, -1.0f, 0.0f}, {0.0f, 1.0f, 0.0f}};
  builder.insert_scan(points, origins);
  octomap::OcTree& tree = builder.tree();
  for (const float y : {-1.0f, 1.0f}) {
    const auto* hit = tree.search(4.01, y + 0.01, 0.01);
    ASSERT_NE(hit, nullptr);
    EXPECT_TRUE(tree.isNodeOccupied(hit));
    const auto* on_ray = tree.search(2.01, y + 0.01, 0.01);
    ASSERT_NE(on_ray, nullptr);
    EXPECT_FALSE(tree.isNodeOccupied(on_ray));
  }
  EXPECT_EQ(tree.search(2.01, 0.01, 0.01), nullptr);  // no ray from the origin (0, 0, 0)
  EXPECT_THROW(builder.insert_scan(points, std::vector<Eigen::Vector3f>(1)), std::invalid_argument);
}

// The default writes free space in 20 cm cells where no surface is known: the same wall
// as above gives the same occupied cells as leaf-by-leaf carving, known free space in
// front of it, and stays unknown behind it.
TEST(Export, CoarseFreeSpaceKeepsSurfacesAndLeavesBehindThemUnknown) {
  std::vector<Eigen::Vector3f> wall;
  for (float y = -1.0f; y <= 1.0f; y += 0.02f) {
    for (float z = -0.5f; z <= 0.5f; z += 0.02f) wall.emplace_back(4.0f, y, z);
  }
  OccupancyOptions exact;
  exact.free_space_cell_m = 0.0;
  OccupancyMapBuilder fine(exact), coarse;
  fine.insert_scan(wall, Eigen::Vector3d::Zero());
  coarse.insert_scan(wall, Eigen::Vector3d::Zero());
  std::size_t occupied_fine = 0, occupied_coarse = 0;
  for (auto it = fine.tree().begin_leafs(); it != fine.tree().end_leafs(); ++it) {
    if (fine.tree().isNodeOccupied(*it)) occupied_fine += std::size_t{1} << (3 * (16 - it.getDepth()));
  }
  for (auto it = coarse.tree().begin_leafs(); it != coarse.tree().end_leafs(); ++it) {
    if (coarse.tree().isNodeOccupied(*it)) occupied_coarse += std::size_t{1} << (3 * (16 - it.getDepth()));
  }
  EXPECT_EQ(occupied_coarse, occupied_fine);
  EXPECT_GT(occupied_coarse, 500u);
  EXPECT_LT(coarse.tree().size(), fine.tree().size());  // the point of coarse cells
  const auto* between = coarse.tree().search(2.0, 0.1, 0.1);
  ASSERT_NE(between, nullptr);
  EXPECT_FALSE(coarse.tree().isNodeOccupied(between));
  EXPECT_EQ(coarse.tree().search(4.3, 0.1, 0.1), nullptr);
}

TEST(Export, ColorOcTreeWriteThenReadRoundTrips) {
  const auto dir = temp_dir();
  const auto points = sample_points();
  write_color_octree((dir / "map_rgb.ot").string(), points, 0.05);
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read((dir / "map_rgb.ot").string()));
  ASSERT_NE(tree, nullptr);
  auto* color = dynamic_cast<octomap::ColorOcTree*>(tree.get());
  ASSERT_NE(color, nullptr);
  for (const MapPoint& p : points) {
    auto* node = color->search(p.position_m.x(), p.position_m.y(), p.position_m.z());
    if (!p.has_rgb) continue;
    ASSERT_NE(node, nullptr);
    EXPECT_TRUE(color->isNodeOccupied(node));
    const auto c = node->getColor();
    EXPECT_EQ(c.r, p.rgb[0]);
    EXPECT_EQ(c.g, p.rgb[1]);
    EXPECT_EQ(c.b, p.rgb[2]);
  }
}

TEST(Export, ThermalOcTreeIsRegisteredAndReadsBack) {
  const auto dir = temp_dir();
  const auto points = sample_points();
  write_thermal_octree((dir / "map_thermal.ot").string(), points, 0.05);
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read((dir / "map_thermal.ot").string()));
  ASSERT_NE(tree, nullptr);
  EXPECT_EQ(tree->getTreeType(), "ThermalOcTree");
  auto* thermal = dynamic_cast<ThermalOcTree*>(tree.get());
  ASSERT_NE(thermal, nullptr);
  int checked = 0;
  for (const MapPoint& p : points) {
    auto* node = thermal->search(p.position_m.x(), p.position_m.y(), p.position_m.z());
    if (std::isnan(p.temperature_k)) {
      EXPECT_EQ(node, nullptr);
      continue;
    }
    ASSERT_NE(node, nullptr);
    EXPECT_TRUE(thermal->isNodeOccupied(node));
    EXPECT_EQ(node->temperature_k(), p.temperature_k);
    ++checked;
  }
  EXPECT_EQ(checked, 40);
  // Inner nodes carry the mean of their children: the root is within the leaves' range.
  const float root = thermal->getRoot()->temperature_k();
  EXPECT_GT(root, 280.0f);
  EXPECT_LT(root, 280.0f + 0.37f * 50);
}

// A map where no point took a colour (a thermal-only or LIDAR-only rig): the ColorOcTree
// is empty, and is written as a valid tree without nodes (octomap's ColorOcTree
// dereferences the missing root when asked to update its inner nodes).
TEST(Export, ColorOcTreeOfAMapWithoutColourIsAnEmptyTree) {
  const auto dir = temp_dir();
  auto points = sample_points();
  for (MapPoint& p : points) p.has_rgb = false;
  write_color_octree((dir / "map_rgb.ot").string(), points, 0.05);
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read((dir / "map_rgb.ot").string()));
  ASSERT_NE(tree, nullptr);
  auto* color = dynamic_cast<octomap::ColorOcTree*>(tree.get());
  ASSERT_NE(color, nullptr);
  EXPECT_EQ(color->size(), 0u);
  for (MapPoint& p : points) p.temperature_k = std::numeric_limits<float>::quiet_NaN();
  write_thermal_octree((dir / "map_thermal.ot").string(), points, 0.05);
  std::unique_ptr<octomap::AbstractOcTree> thermal(octomap::AbstractOcTree::read((dir / "map_thermal.ot").string()));
  ASSERT_NE(dynamic_cast<ThermalOcTree*>(thermal.get()), nullptr);
  EXPECT_EQ(thermal->size(), 0u);
}

namespace {

/// A file size limit (RLIMIT_FSIZE) for the current scope: writes beyond it fail with EFBIG
/// as on a full disk (SIGXFSZ ignored, as a write error instead of a signal).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &saved_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    ::setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &saved_);
    std::signal(SIGXFSZ, old_handler_);
  }

 private:
  rlimit saved_{};
  void (*old_handler_)(int) = SIG_DFL;
};

std::vector<MapPoint> many_points(int n) {
  std::vector<MapPoint> points;
  for (int i = 0; i < n; ++i) {
    MapPoint p;
    p.position_m = Eigen::Vector3f(0.1f * (i % 40), 0.1f * ((i / 40) % 40), 0.1f * (i / 1600));
    p.rgb = {static_cast<std::uint8_t>(i), 200, 7};
    p.has_rgb = true;
    p.temperature_k = 280.0f + 0.01f * i;
    points.push_back(p);
  }
  return points;
}

}  // namespace

// Every map writer on a full disk (here: a file size limit, which works as root too)
// throws an error naming the final path, and leaves neither that file nor a temporary one.
TEST(Export, WritersOnAFullDiskThrowNamingTheFileAndLeaveNothing) {
  const auto dir = temp_dir();
  const auto points = many_points(8000);  // every file > 4 kB
  OccupancyMapBuilder occupancy(OccupancyOptions{});
  std::vector<Eigen::Vector3f> scan;
  for (const MapPoint& p : points) scan.push_back(p.position_m + Eigen::Vector3f(3.0f, 0.0f, 0.0f));
  occupancy.insert_scan(scan, Eigen::Vector3d::Zero());
  const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> writers = {
      {"map.ply", [&](const std::string& p) { write_ply(p, points); }},
      {"map.pcd", [&](const std::string& p) { write_pcd(p, points); }},
      {"map.bt", [&](const std::string& p) { occupancy.write_bt(p); }},
      {"map_rgb.ot", [&](const std::string& p) { write_color_octree(p, points, 0.05); }},
      {"map_thermal.ot", [&](const std::string& p) { write_thermal_octree(p, points, 0.05); }},
  };
  for (const auto& [name, write] : writers) {
    const std::string path = (dir / name).string();
    {
      FileSizeLimit limit(4 * 1024);
      try {
        write(path);
        ADD_FAILURE() << name << ": no error on a full disk";
      } catch (const rgbdt::core::Error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      }
    }
    EXPECT_FALSE(fs::exists(path)) << name << " left half-written";
    // Without the limit the same call writes the whole file.
    write(path);
    EXPECT_GT(fs::file_size(path), 4u * 1024u) << name;
  }
  std::vector<std::string> left;
  for (const auto& entry : fs::directory_iterator(dir)) left.push_back(entry.path().filename().string());
  EXPECT_EQ(left.size(), writers.size()) << "temporary files left behind";
}
