// Uses the installed rgbdt: projects a point with an extrinsic and a camera model.
#include <rgbdt/cloud/point_types.hpp>
#include <rgbdt/core/camera.hpp>
#include <rgbdt/core/extrinsics.hpp>

#include <iostream>

int main() {
  rgbdt::core::CameraIntrinsics intr;
  intr.width = 640;
  intr.height = 512;
  intr.fx = intr.fy = 417.2;
  intr.cx = 320;
  intr.cy = 256;
  intr.distortion = {0, 0, 0, 0, 0};
  const rgbdt::core::PinholeCamera camera(intr);
  rgbdt::core::Extrinsics e;
  e.T_parent_child = rgbdt::core::from_vector6((rgbdt::core::Vector6d() << 0, 0, 0, 0.1, 0, 0).finished());
  rgbdt::cloud::PointXYZIRT p;
  p.x = 0;
  p.y = 0;
  p.z = 5;
  Eigen::Vector2d uv;
  if (!camera.project(e.T_parent_child * Eigen::Vector3d(p.x, p.y, p.z), &uv)) return 1;
  std::cout << "consumer: projected to " << uv.transpose() << "\n";
  return std::abs(uv.x() - (320 + 417.2 * 0.1 / 5)) < 1e-9 ? 0 : 1;
}
