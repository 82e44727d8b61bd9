// Real data: ART-BP/calib (../shared/data/art-bp-calib, GPL-2.0, read in place through the
// session the fixture real_data_art_bp_session writes). A 16-ring Hesai LIDAR and a 1920x1080
// fisheye camera see a 1.4 x 1.0 m board with 4 holes of radius 0.12 m, 0.5 m apart
// horizontally and 0.4 m vertically, from about 2.6 m in 3 poses (left, mid, right).
//
// What the data can support, which sets the tolerances below:
// - The rings are 2 deg apart: 9 cm on the board at 2.6 m, so each hole (24 cm across) is
//   crossed by 2 rings only. Along a ring the returns are 0.09 deg apart (4 mm), so each
//   chord's ends are known to a few mm (plus a beam-footprint bias of the same order). The
//   horizontal centre is the chords' midpoint: a few mm. The vertical centre comes from the
//   chords' lengths and the known radius: with half-chord h ~ 0.11 m at distance d ~ 0.045 m
//   from the centre, dd = (h / d) dh ~ 2.5 dh, i.e. about 1 cm for dh = 4 mm.
// - The authors' own extrinsic moved by 0.2 deg and 6 mm between their two published runs
//   on these scenes (_history/080943f vs 8628e54): 0.2 deg at 2.6 m is 9 mm, 4.2 px at
//   fx = 1204 px.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/session.hpp"

namespace rgbdt {
namespace {

namespace fs = std::filesystem;
namespace ct = calib_targets;

const std::array<const char*, 3> kPoses = {"left", "mid", "right"};  // session view order
constexpr double kHoleRadiusM = 0.12;
constexpr double kHoleDxM = 0.5;  // authors' delta_width_circles
constexpr double kHoleDyM = 0.4;  // authors' delta_height_circles

// Horizontal spacing: two chord midpoints, each a few mm (see the file comment); 1.5 cm
// leaves room for a 2-3 mm footprint bias that does not cancel when a hole's two chords sit
// on different sides of the beam.
constexpr double kSpacingTolXM = 0.015;
// Vertical spacing: two vertical centres of about 1 cm each -> 1.4 cm combined; 3 cm is
// about 2 sigma.
constexpr double kSpacingTolYM = 0.03;
// Measured radius: the free-radius fit to two chords has one degree of freedom to spare, so
// it carries the 1 cm vertical uncertainty too; the issue reports LIDAR radii 4-7 mm too
// large from the beam footprint on another sensor. 2 cm bounds both.
constexpr double kRadiusTolM = 0.02;
// Holes of one board lie in one plane within the ring noise (Hesai: ~2 cm range noise,
// averaged over the ~20 edge points of a hole): 2 cm.
constexpr double kPlanarityTolM = 0.02;

fs::path session_dir() { return fs::path(ART_BP_SESSION_DIR); }

core::CalibrationSession load_session() {
  const fs::path yaml = session_dir() / "session.yaml";
  if (!fs::exists(yaml)) {
    ADD_FAILURE() << "missing " << yaml << ": run the fixture (ctest -R real_data_art_bp_session)";
    return {};
  }
  return core::read_calibration_session(yaml.string());
}

// The authors' T_camera_lidar (p_cam = Rcl p_lidar + Pcl), written by the fixture.
Eigen::Isometry3d reference_T_camera_lidar() {
  return core::read_extrinsics((session_dir() / "reference" / "extrinsics_rgb.yaml").string(),
                               core::ExtrinsicsFrames{"rgb"})
      .T_parent_child;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

ct::LidarTargetDetection detect_lidar(const core::CalibrationSession& s, int view) {
  const cloud::LoadedCloud loaded = cloud::load_pcd(s.views.at(view).cloud);
  EXPECT_TRUE(loaded.has_ring) << s.views.at(view).cloud << " has no ring field";
  const auto t0 = std::chrono::steady_clock::now();
  ct::LidarTargetDetection d = ct::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, s.target);
  std::printf("[%s] LIDAR detection %.0f ms on %zu points: %s, method %s\n", kPoses[view],
              ms_since(t0), loaded.cloud->size(), d.ok ? "ok" : d.reason.c_str(),
              d.edge_method.c_str());
  for (size_t k = 0; k < d.holes.size(); ++k) {
    const auto& h = d.holes[k];
    std::printf("  hole %zu: centre [%.4f %.4f %.4f] m, radius %.4f m (%s), %zu edge points, rms %.4f m\n", k,
                h.center.x(), h.center.y(), h.center.z(), h.radius_m,
                h.radius_measured ? "measured" : "not measured", h.edge_points.size(), h.rms_m);
  }
  return d;
}

ct::ImageTargetDetection detect_image(const core::CalibrationSession& s, int view) {
  const core::PinholeCamera camera(core::read_camera_info(s.cameras.at("rgb").intrinsics));
  const std::string path = s.views.at(view).images.at("rgb");
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  EXPECT_FALSE(image.empty()) << "cannot read " << path;
  const auto t0 = std::chrono::steady_clock::now();
  ct::ImageTargetDetection d = ct::detect_target_in_image(image, s.target, camera);
  std::printf("[%s] image detection %.0f ms: %s\n", kPoses[view], ms_since(t0),
              d.ok ? "ok" : d.reason.c_str());
  for (size_t k = 0; k < d.holes.size(); ++k) {
    const auto& h = d.holes[k];
    std::printf("  hole %zu: centre [%.1f %.1f] px, ellipse %.1f x %.1f px, %zu edge points\n", k,
                h.center_px.x(), h.center_px.y(), h.ellipse.size.width, h.ellipse.size.height,
                h.edge_points_px.size());
  }
  return d;
}

// Independent ground truth for the image holes: the board's 4 ArUco markers (authors'
// config: centres at (+-delta_width_qr_center, +-delta_height_qr_center) = (+-0.55, +-0.35) m)
// give the board's pose by planar PnP on the undistorted marker centres, and the hole
// centres of the layout are projected from that pose. The dictionary is not in the config:
// the first of the common ones that finds exactly 4 markers is used. Markers are assigned to
// the layout by quadrant around their centroid (board upright in every pose).
struct ArucoHoles {
  std::vector<Eigen::Vector2d> holes_px;  // layout order, top-left first
  std::string dictionary;
};

std::optional<ArucoHoles> holes_from_aruco(const cv::Mat& image, const core::PinholeCamera& camera,
                                           const core::TargetSpec& target) {
  const std::pair<int, const char*> dictionaries[] = {
      {cv::aruco::DICT_6X6_250, "6X6_250"}, {cv::aruco::DICT_5X5_250, "5X5_250"},
      {cv::aruco::DICT_4X4_250, "4X4_250"}, {cv::aruco::DICT_7X7_250, "7X7_250"},
      {cv::aruco::DICT_ARUCO_ORIGINAL, "ARUCO_ORIGINAL"}};
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  for (const auto& [id, name] : dictionaries) {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    const cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
    params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::detectMarkers(grey, cv::aruco::getPredefinedDictionary(id), corners, ids, params);
    if (corners.size() != 4) continue;
    // Marker centres as undistorted normalised points (the diagonals' crossing of the
    // undistorted corners: a square's centre under perspective).
    std::vector<Eigen::Vector2d> centres;
    for (const auto& c : corners) {
      std::array<Eigen::Vector3d, 4> ray;
      for (int k = 0; k < 4; ++k) ray[k] = camera.unproject(Eigen::Vector2d(c[k].x, c[k].y));
      const Eigen::Vector3d x = ray[0].cross(ray[2]).cross(ray[1].cross(ray[3]));
      centres.emplace_back(x.x() / x.z(), x.y() / x.z());
    }
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& c : centres) mean += c / 4.0;
    std::vector<cv::Point3d> object(4);
    std::vector<cv::Point2d> normalised(4);
    for (const auto& c : centres) {
      const int col = c.x() > mean.x() ? 1 : 0, row = c.y() > mean.y() ? 1 : 0;  // image y down
      const int k = 2 * row + col;
      object[k] = cv::Point3d(col ? 0.55 : -0.55, row ? -0.35 : 0.35, 0.0);
      normalised[k] = cv::Point2d(c.x(), c.y());
    }
    cv::Vec3d rvec, tvec;
    if (!cv::solvePnP(object, normalised, cv::Matx33d::eye(), cv::noArray(), rvec, tvec, false,
                      cv::SOLVEPNP_IPPE))
      continue;
    cv::Matx33d R;
    cv::Rodrigues(rvec, R);
    ArucoHoles out{{}, name};
    for (const Eigen::Vector2d& hole : ct::target_layout(target)) {
      const cv::Vec3d p = R * cv::Vec3d(hole.x(), hole.y(), 0.0) + tvec;
      Eigen::Vector2d px;
      if (!camera.project(Eigen::Vector3d(p[0], p[1], p[2]), &px)) return std::nullopt;
      out.holes_px.push_back(px);
    }
    return out;
  }
  return std::nullopt;
}

class ArtBpPose : public ::testing::TestWithParam<int> {};

// (a) The 4 holes in each pose's cloud, in the board's layout and of its radius.
TEST_P(ArtBpPose, LidarFindsTheFourHolesInTheirLayout) {
  const core::CalibrationSession s = load_session();
  ASSERT_EQ(s.views.size(), kPoses.size());
  const int v = GetParam();
  const ct::LidarTargetDetection d = detect_lidar(s, v);
  ASSERT_TRUE(d.ok) << kPoses[v] << ": " << d.reason;
  ASSERT_EQ(d.holes.size(), 4u);
  const auto& h = d.holes;  // row-major, top-left first: 0 1 / 2 3
  EXPECT_NEAR((h[1].center - h[0].center).norm(), kHoleDxM, kSpacingTolXM) << "top row";
  EXPECT_NEAR((h[3].center - h[2].center).norm(), kHoleDxM, kSpacingTolXM) << "bottom row";
  EXPECT_NEAR((h[2].center - h[0].center).norm(), kHoleDyM, kSpacingTolYM) << "left column";
  EXPECT_NEAR((h[3].center - h[1].center).norm(), kHoleDyM, kSpacingTolYM) << "right column";
  const Eigen::Vector3d n = d.plane.head<3>();
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(n.dot(h[k].center) + d.plane(3), 0.0, kPlanarityTolM) << "hole " << k;
    // The board stands 2.4-2.8 m from the LIDAR in every pose (its returns, fixture data).
    EXPECT_GT(h[k].center.norm(), 2.2) << "hole " << k;
    EXPECT_LT(h[k].center.norm(), 3.0) << "hole " << k;
    if (h[k].radius_measured) {
      EXPECT_NEAR(h[k].radius_m, kHoleRadiusM, kRadiusTolM) << "hole " << k;
    }
  }
}

// (b) The 4 holes in each fisheye image.
TEST_P(ArtBpPose, ImageFindsTheFourHoles) {
  const core::CalibrationSession s = load_session();
  ASSERT_EQ(s.views.size(), kPoses.size());
  const int v = GetParam();
  const core::PinholeCamera camera(core::read_camera_info(s.cameras.at("rgb").intrinsics));
  const auto aruco = holes_from_aruco(cv::imread(s.views.at(v).images.at("rgb")), camera, s.target);
  ASSERT_TRUE(aruco) << kPoses[v] << ": the board's 4 ArUco markers are not found";
  for (int k = 0; k < 4; ++k)
    std::printf("[%s] hole %d: ArUco (%s) puts it at [%.1f %.1f] px\n", kPoses[v], k,
                aruco->dictionary.c_str(), aruco->holes_px[k].x(), aruco->holes_px[k].y());
  const ct::ImageTargetDetection d = detect_image(s, v);
  ASSERT_TRUE(d.ok) << kPoses[v] << ": " << d.reason;
  ASSERT_EQ(d.holes.size(), 4u);
  // A checkerboard or a door shows through every hole: found from the board's side.
  EXPECT_EQ(d.method, "holes of the board");
  // The marker pose: 4 sub-pixel centres 1.1 x 0.7 m apart put the holes within about 1 px;
  // the ellipse centre of a hole is off the projected circle centre by well under 1 px at
  // this size and tilt; the hole edges against a textured background (a checkerboard shows
  // through the right-hand holes) may move a fitted ellipse by a pixel or two: 4 px.
  constexpr double kTolPx = 4.0;
  for (int k = 0; k < 4; ++k) {
    const double err = (d.holes[k].center_px - aruco->holes_px[k]).norm();
    std::printf("[%s] hole %d: detected %.1f px from the ArUco prediction\n", kPoses[v], k, err);
    EXPECT_LT(err, kTolPx) << kPoses[v] << " hole " << k;
  }
}

// (a) against the authors' result: the LIDAR hole centres, taken into the camera by their
// extrinsic and projected by the equidistant model, land where the board's ArUco markers
// put the holes in the image (independent of the image hole detector).
TEST_P(ArtBpPose, LidarHolesLandOnTheImageHolesUnderTheAuthorsExtrinsic) {
  const core::CalibrationSession s = load_session();
  ASSERT_EQ(s.views.size(), kPoses.size());
  const int v = GetParam();
  const ct::LidarTargetDetection lidar = detect_lidar(s, v);
  ASSERT_TRUE(lidar.ok && lidar.holes.size() == 4) << kPoses[v] << " LIDAR: " << lidar.reason;
  const core::PinholeCamera camera(core::read_camera_info(s.cameras.at("rgb").intrinsics));
  const auto aruco = holes_from_aruco(cv::imread(s.views.at(v).images.at("rgb")), camera, s.target);
  ASSERT_TRUE(aruco) << kPoses[v] << ": the board's 4 ArUco markers are not found";
  const Eigen::Isometry3d T = reference_T_camera_lidar();
  // 1 cm of LIDAR centre error (file comment) is 4.6 px at 2.6 m, the authors' 0.2 deg
  // another 4.2 px, the ArUco prediction about 1 px: 10 px is about 2 sigma.
  constexpr double kTolPx = 10.0;
  for (int k = 0; k < 4; ++k) {
    Eigen::Vector2d px;
    ASSERT_TRUE(camera.project(T * lidar.holes[k].center, &px)) << "hole " << k << " behind the camera";
    const double err = (px - aruco->holes_px[k]).norm();
    std::printf("[%s] hole %d: LIDAR centre projects to [%.1f %.1f] px, ArUco [%.1f %.1f] px, %.1f px apart\n",
                kPoses[v], k, px.x(), px.y(), aruco->holes_px[k].x(), aruco->holes_px[k].y(), err);
    EXPECT_LT(err, kTolPx) << kPoses[v] << " hole " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(RealData, ArtBpPose, ::testing::Values(0, 1, 2),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return std::string(kPoses[info.param]);
                         });

}  // namespace
}  // namespace rgbdt
