// Uses the installed rgbdt: recovers a known T_camera_lidar from three simulated circle
// views with rgbdt::extrinsics, the way another robot would use the module.
#include <rgbdt/core/camera.hpp>
#include <rgbdt/core/transform.hpp>
#include <rgbdt/extrinsics/edge_alignment.hpp>

#include <cmath>
#include <iostream>

int main() {
  using namespace rgbdt;
  core::CameraIntrinsics intr;
  intr.width = 1288;
  intr.height = 964;
  intr.fx = intr.fy = 1335.0;
  intr.cx = 644;
  intr.cy = 482;
  intr.distortion = {0, 0, 0, 0, 0};
  const core::PinholeCamera camera(intr);
  // Camera looks along the LIDAR's x axis, 10 cm to the side.
  const Eigen::Isometry3d T_camera_lidar = core::make_transform(
      core::rotation_from_rpy(-M_PI / 2, 0, -M_PI / 2).transpose(), {0.1, -0.05, 0.02});

  std::vector<extrinsics::TargetView> views;
  const double radius = 0.3;
  const Eigen::Vector3d centres[] = {{5, 0.6, 0.2}, {6, -0.7, -0.3}, {4.5, 0.1, 0.5}};
  for (const auto& c : centres) {
    extrinsics::TargetView v;
    v.radius_m = radius;
    v.image_width = intr.width;
    v.image_height = intr.height;
    const Eigen::Vector3d n = (-c).normalized();
    const Eigen::Vector3d a = n.cross(Eigen::Vector3d::UnitZ()).normalized(), b = n.cross(a);
    for (int k = 0; k < 360; ++k) {
      const double t = k * M_PI / 180.0;
      const Eigen::Vector3d p = c + radius * (std::cos(t) * a + std::sin(t) * b);
      v.lidar_circle_points.push_back(p);
      Eigen::Vector2d uv;
      if (camera.project(T_camera_lidar * p, &uv)) v.image_edge_points_px.push_back(uv);
    }
    v.lidar_centers.push_back(c);
    v.lidar_normals.push_back(n);
    // The hole's image ellipse (its centre seeds the coarse stage that widens the basin).
    Eigen::Vector2d centre_px;
    if (camera.project(T_camera_lidar * c, &centre_px)) {
      const float diameter_px = static_cast<float>(2 * radius * intr.fx / c.norm());
      v.image_ellipses.emplace_back(cv::Point2f(centre_px.x(), centre_px.y()),
                                    cv::Size2f(diameter_px, diameter_px), 0.0f);
    }
    views.push_back(v);
  }
  const Eigen::Isometry3d guess =
      core::from_vector6(core::to_vector6(T_camera_lidar) +
                         (core::Vector6d() << 0.05, -0.05, 0.03, 0.1, -0.1, 0.05).finished());
  const auto result = extrinsics::align_edges(views, camera, {}, guess);
  // And with no guess at all: the closed-form start from the same holes.
  const auto unguided = extrinsics::align_edges(views, camera);
  const double dr0 = core::rotation_error_rad(unguided.T_camera_lidar, T_camera_lidar) * 180 / M_PI;
  const double dt0 = core::translation_error_m(unguided.T_camera_lidar, T_camera_lidar);
  std::cout << "consumer: with no guess, within " << dr0 << " deg, " << dt0 * 100 << " cm\n";
  const double dr = core::rotation_error_rad(result.T_camera_lidar, T_camera_lidar) * 180 / M_PI;
  const double dt = core::translation_error_m(result.T_camera_lidar, T_camera_lidar);
  std::cout << "consumer: recovered T_camera_lidar within " << dr << " deg, " << dt * 100
            << " cm\n";
  const bool ok = result.converged && dr < 0.01 && dt < 0.001;
  const bool ok0 = unguided.converged && dr0 < 0.01 && dt0 < 0.001;
  return (ok && ok0) ? 0 : 1;
}
