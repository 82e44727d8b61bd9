// End-to-end test of `rgbdt_coloring_error --setup`: writes a Sec. 4.4 session (card before
// cloth at the paper's five depths: PCD clouds, PNG images, session.yaml, true_calib/) and a
// calibration folder with a slightly wrong extrinsic, runs the app and checks its Table 2.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "card_scene.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/test/test_util.hpp"

namespace fs = std::filesystem;

namespace rgbdt::error_model {
namespace {

using namespace test;  // NOLINT: the scene helpers

using rgbdt::test::temp_dir;

std::string app_path() {
  const char* bin = std::getenv("RGBDT_BIN_DIR");
  return ((bin ? fs::path(bin) : fs::path(RGBDT_BINARY_DIR) / "bin") / "rgbdt_coloring_error").string();
}

/// Table rows "| depth | x | y | predicted x | predicted y | expected x | expected y | ..."
std::vector<std::vector<double>> table_rows(const std::string& markdown) {
  std::vector<std::vector<double>> rows;
  std::istringstream in(markdown);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("| ", 0) != 0 || line.find("depth") != std::string::npos) continue;
    std::vector<double> row;
    std::istringstream cells(line);
    std::string cell;
    std::getline(cells, cell, '|');  // before the first bar
    while (std::getline(cells, cell, '|')) {
      try {
        row.push_back(std::stod(cell));
      } catch (const std::exception&) {
        row.push_back(std::nan(""));
      }
    }
    rows.push_back(row);
  }
  return rows;
}

TEST(ColoringSetupApp, MeasuresTheBandTheWrongExtrinsicCausesAtEveryDepth) {
  const fs::path dir = temp_dir("session");
  const core::PinholeCamera camera = rgb_camera();
  const Eigen::Isometry3d T_true = true_T_camera_lidar();
  core::Vector6d dv;
  dv << 0.2 * kDeg, 0.15 * kDeg, 0.05 * kDeg, 0.005, 0.0, 0.0;
  const Eigen::Isometry3d T_est = core::from_vector6(dv) * T_true;

  fs::create_directories(dir / "clouds");
  fs::create_directories(dir / "rgb");
  fs::create_directories(dir / "true_calib");
  fs::create_directories(dir / "calib");
  core::write_camera_info((dir / "rgb.yaml").string(), camera.intrinsics());
  core::write_camera_info((dir / "true_calib" / "rgb.yaml").string(), camera.intrinsics());
  core::Extrinsics truth{"rgb", "lidar", T_true, std::nullopt};
  core::write_extrinsics((dir / "true_calib" / "extrinsics_rgb.yaml").string(), truth);
  core::Vector6d sigma;
  sigma << 0.15 * kDeg, 0.15 * kDeg, 0.1 * kDeg, 0.005, 0.005, 0.01;
  core::Extrinsics estimate{"rgb", "lidar", T_est, core::Matrix6d(sigma.cwiseAbs2().asDiagonal())};
  core::write_extrinsics((dir / "calib" / "extrinsics_rgb.yaml").string(), estimate);

  // Both layouts read_setup_session accepts: a 'views' list (calibration layout) and, in a
  // second folder over the same files, clouds and frames indexed by time (mapping layout, as
  // rgbdt_sim coloring-setup writes).
  std::ofstream yaml(dir / "session.yaml");
  yaml << "cameras:\n  rgb: {intrinsics: rgb.yaml}\nviews:\n";
  std::vector<core::TimedFile> cloud_index, frame_index;
  const double depths[] = {5.0, 7.5, 10.0, 12.0, 15.0};
  for (int i = 0; i < 5; ++i) {
    const Scene scene(depths[i]);
    cloud::Cloud cloud;
    for (const auto& p : scan(scene, 20 + i)) {
      cloud::PointXYZIRT q;
      q.x = static_cast<float>(p.x());
      q.y = static_cast<float>(p.y());
      q.z = static_cast<float>(p.z());
      cloud.push_back(q);
    }
    const std::string name = "00" + std::to_string(i);
    cloud::save_pcd((dir / "clouds" / (name + ".pcd")).string(), cloud);
    const GrayImage image = render(scene, camera, T_true);
    cv::Mat png(image.height, image.width, CV_32F, const_cast<float*>(image.pixels.data()));
    cv::Mat png8;
    png.convertTo(png8, CV_8U);
    ASSERT_TRUE(cv::imwrite((dir / "rgb" / (name + ".png")).string(), png8));
    yaml << "  - {cloud: clouds/" << name << ".pcd, images: {rgb: rgb/" << name << ".png}}\n";
    cloud_index.push_back({10.0 * i, (dir / "clouds" / (name + ".pcd")).string()});
    frame_index.push_back({10.0 * i + 0.01, (dir / "rgb" / (name + ".png")).string()});
  }
  yaml.close();
  core::write_time_index((dir / "clouds" / "index.csv").string(), cloud_index);
  core::write_time_index((dir / "rgb" / "index.csv").string(), frame_index);
  core::MappingSession mapping;
  mapping.lidar.clouds = (dir / "clouds" / "index.csv").string();
  mapping.cameras["rgb"].intrinsics = (dir / "rgb.yaml").string();
  mapping.cameras["rgb"].frames = (dir / "rgb" / "index.csv").string();
  fs::create_directories(dir / "mapping_layout" / "true_calib");
  fs::copy(dir / "true_calib", dir / "mapping_layout" / "true_calib", fs::copy_options::recursive);
  core::write_mapping_session((dir / "mapping_layout" / "session.yaml").string(), mapping);

  for (const fs::path& session : {dir, dir / "mapping_layout"}) {
    SCOPED_TRACE(session.string());
    const fs::path out = session / "out";
    const std::string command = app_path() + " --setup " + session.string() + " --calib " + (dir / "calib").string() +
                                " --report " + out.string() + " > " + (session / "stdout.txt").string() + " 2>&1";
    ASSERT_EQ(std::system(command.c_str()), 0) << command << "\n" << std::ifstream(session / "stdout.txt").rdbuf();
    std::ifstream report(out / "coloring_setup.md");
    ASSERT_TRUE(report.good()) << "no " << (out / "coloring_setup.md");
    std::stringstream text;
    text << report.rdbuf();
    const auto rows = table_rows(text.str());
    ASSERT_EQ(rows.size(), 5u) << text.str();
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      ASSERT_GE(r.size(), 11u) << text.str();
      // Columns: depth, x, y, predicted x, y, expected x, y, truth x, y, paper x, y, points.
      EXPECT_NEAR(r[0], Scene(depths[i]).card_centre.norm(), 0.05);
      // Measured vs the band the extrinsic error causes: 0.2 point spacing + half a pixel,
      // the tolerance of the library test (coloring_band_test.cpp), in cm.
      const double spacing_x_cm = 100.0 * depths[i] * 0.25 * kDeg, spacing_y_cm = 100.0 * depths[i] * 0.2 * kDeg;
      const double half_pixel_cm = 100.0 * 0.5 * depths[i] / camera.intrinsics().fx;
      EXPECT_NEAR(r[1], r[5], 0.2 * spacing_x_cm + half_pixel_cm + 0.05) << "depth " << depths[i];  // + table rounding
      EXPECT_NEAR(r[2], r[6], 0.2 * spacing_y_cm + half_pixel_cm + 0.05) << "depth " << depths[i];
      // The true calibration leaves (almost) no band: under one point spacing.
      EXPECT_LT(r[7], spacing_x_cm);
      EXPECT_LT(r[8], spacing_y_cm);
      // The model's 95 % band covers the error actually made (it is ~1 sigma of the covariance).
      EXPECT_LE(r[5], r[3]);
      EXPECT_LE(r[6], r[4]);
    }
  }
}

TEST(ColoringSetupApp, ReportsAMissingSessionClearly) {
  const fs::path dir = temp_dir("missing");
  const std::string command = app_path() + " --setup " + (dir / "nope").string() + " --calib " + dir.string() + " > " +
                              (dir / "out.txt").string() + " 2>&1";
  EXPECT_NE(std::system(command.c_str()), 0);
  std::stringstream text;
  text << std::ifstream(dir / "out.txt").rdbuf();
  EXPECT_NE(text.str().find("nope"), std::string::npos) << text.str();
}

}  // namespace
}  // namespace rgbdt::error_model
