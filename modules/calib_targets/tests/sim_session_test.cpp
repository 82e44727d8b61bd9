// Detection on a simulated calibration session (rgbdt::sim) against its ground truth.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/sim/calibration_session.hpp"

namespace ct = rgbdt::calib_targets;
namespace fs = std::filesystem;

TEST(SimSession, TenViewsDetectedAgainstGroundTruth) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "calib_targets_sim_session";
  fs::remove_all(dir);
  rgbdt::sim::CalibrationSessionOptions opt;
  opt.views = 10;
  opt.seed = 3;
  opt.min_distance_m = 3.0;  // the range for the 1 cm requirement
  opt.max_distance_m = 5.0;
  const auto truth = rgbdt::sim::write_calibration_session(dir.string(), opt);
  const auto session = rgbdt::core::read_calibration_session(dir.string());
  ASSERT_EQ(session.views.size(), 10u);
  std::map<std::string, rgbdt::core::PinholeCamera> cams;
  std::map<std::string, Eigen::Isometry3d> T_cam_lidar;
  for (const auto& [name, entry] : session.cameras) {
    cams.emplace(name, rgbdt::core::PinholeCamera(rgbdt::core::read_camera_info(entry.intrinsics)));
    T_cam_lidar[name] = rgbdt::core::read_extrinsics((dir / "true_calib" / ("extrinsics_" + name + ".yaml")).string()).T_parent_child;
  }
  double worst_center = 0.0;
  std::map<std::string, double> worst_edge_p95;
  for (std::size_t v = 0; v < session.views.size(); ++v) {
    const auto loaded = rgbdt::cloud::load_pcd(session.views[v].cloud);
    const auto det = ct::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, session.target);
    ASSERT_TRUE(det.ok) << "view " << v << ": " << det.reason;  // every view, automatically
    ASSERT_EQ(det.holes.size(), truth.views[v].hole_centers_lidar.size());
    for (std::size_t h = 0; h < det.holes.size(); ++h) {
      const double e = (det.holes[h].center - truth.views[v].hole_centers_lidar[h]).norm();
      worst_center = std::max(worst_center, e);
      EXPECT_LT(e, 0.01) << "view " << v << " hole " << h;  // issue: 1 cm at 3-5 m, 1 cm noise
    }
    for (const auto& [name, path] : session.views[v].images) {
      const cv::Mat img = cv::imread(path, cv::IMREAD_UNCHANGED);
      const auto& cam = cams.at(name);
      const auto idet = ct::detect_target_in_image(img, session.target, cam);
      ASSERT_TRUE(idet.ok) << "view " << v << " " << name << ": " << idet.reason;
      // True edge: the hole's circle in the LIDAR frame, projected with the true calibration.
      for (std::size_t h = 0; h < idet.holes.size(); ++h) {
        const auto circle = ct::sample_circle(truth.views[v].hole_centers_lidar[h], truth.views[v].normal_lidar,
                                              session.target.radius_m, 0.02);
        std::vector<Eigen::Vector2d> curve;
        for (const auto& p : circle) {
          Eigen::Vector2d px;
          if (cam.project(T_cam_lidar[name] * p, &px)) curve.push_back(px);
        }
        std::vector<double> err;
        for (const auto& e : idet.holes[h].edge_points_px) {
          double best = 1e9;
          for (const auto& c : curve) best = std::min(best, (c - e).norm());
          err.push_back(best);
        }
        std::sort(err.begin(), err.end());
        const double p95 = err[static_cast<std::size_t>(0.95 * static_cast<double>(err.size() - 1))];
        worst_edge_p95[name] = std::max(worst_edge_p95[name], p95);
        EXPECT_LT(p95, 0.5) << "view " << v << " " << name;  // issue: within 0.5 px
      }
    }
  }
  std::cout << "worst hole centre error " << worst_center << " m";
  for (const auto& [name, e] : worst_edge_p95) std::cout << ", " << name << " edge p95 " << e << " px";
  std::cout << "\n";
}
