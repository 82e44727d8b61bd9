#pragma once
/// \file
/// Pinhole camera with plumb_bob (OpenCV k1 k2 p1 p2 k3) or equidistant (OpenCV fisheye
/// k1 k2 k3 k4) distortion. Pixel convention: OpenCV/ROS, the centre of the top-left
/// pixel is (0, 0); u to the right, v down; the camera looks along +z.
#include <Eigen/Core>
#include <cmath>
#include <string>
#include <vector>

namespace rgbdt::core {

enum class DistortionModel {
  kNone,         ///< no distortion (ROS "plumb_bob" with all zeros is also accepted)
  kPlumbBob,     ///< k1 k2 p1 p2 k3 (ROS "plumb_bob", OpenCV default model)
  kEquidistant,  ///< k1 k2 k3 k4 on theta (ROS "equidistant", cv::fisheye)
};

/// The ROS name of a model ("plumb_bob", "equidistant"); kNone maps to "plumb_bob".
std::string to_string(DistortionModel model);
/// Parses a ROS model name; throws std::invalid_argument naming the value otherwise.
DistortionModel distortion_model_from_string(const std::string& name);
/// Number of coefficients the model takes (0, 5, 4).
int distortion_size(DistortionModel model);

/// Largest image width or height the readers accept [px].
constexpr int kMaxImageSide = 20000;

/// Intrinsic parameters, as in the ROS camera_info YAML.
struct CameraIntrinsics {
  std::string camera_name = "camera";
  int width = 0;   ///< [px]
  int height = 0;  ///< [px]
  double fx = 0.0, fy = 0.0;  ///< focal lengths [px]
  double cx = 0.0, cy = 0.0;  ///< principal point [px]
  DistortionModel model = DistortionModel::kPlumbBob;
  /// plumb_bob: k1 k2 p1 p2 k3; equidistant: k1 k2 k3 k4. Shorter vectors are padded with
  /// zeros by validate()-checked constructors.
  std::vector<double> distortion;

  /// Empty when the parameters are usable, else the reason (names the value): image size in
  /// [1, kMaxImageSide], fx, fy finite and > 0, the principal point inside the image
  /// (0 <= cx <= width, 0 <= cy <= height), every coefficient finite.
  std::string validate() const;
};

/// Projection model. Immutable and cheap to copy.
class PinholeCamera {
 public:
  /// Throws std::invalid_argument with the reason if intrinsics.validate() fails.
  explicit PinholeCamera(const CameraIntrinsics& intrinsics);

  const CameraIntrinsics& intrinsics() const { return intrinsics_; }
  int width() const { return intrinsics_.width; }
  int height() const { return intrinsics_.height; }

  /// Projects a point in the camera frame [m] to a pixel. Returns false (and leaves the
  /// outputs untouched) when the point is not in front of the camera (z <= min_depth_m).
  /// J_point, if given, receives d(pixel)/d(point), analytic.
  bool project(const Eigen::Vector3d& point_camera, Eigen::Vector2d* pixel,
               Eigen::Matrix<double, 2, 3>* J_point = nullptr) const;

  /// Normalised, undistorted coordinates (x, y) of a pixel, found by Newton iterations on
  /// the distortion. Returns the ray (x, y, 1).
  Eigen::Vector3d unproject(const Eigen::Vector2d& pixel) const;

  /// True when the pixel lies inside the image, at least margin_px from its border.
  bool in_image(const Eigen::Vector2d& pixel, double margin_px = 0.0) const;

  /// Applies the distortion to normalised coordinates; J (optional) = d(distorted)/d(xy).
  Eigen::Vector2d distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* J = nullptr) const;

  static constexpr double kMinDepthM = 1e-6;

 private:
  CameraIntrinsics intrinsics_;
  double d_[5] = {0, 0, 0, 0, 0};
};

/// Distortion of normalised coordinates, generic in the scalar type so that Ceres can
/// differentiate through it (also with respect to the coefficients d).
/// plumb_bob: d = k1 k2 p1 p2 k3; equidistant: d = k1 k2 k3 k4.
template <typename T>
void distort_generic(DistortionModel model, const T* d, const T& x, const T& y, T* xd, T* yd) {
  using std::atan;
  using std::sqrt;
  if (model == DistortionModel::kPlumbBob) {
    const T r2 = x * x + y * y;
    const T radial = T(1) + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
    *xd = x * radial + T(2) * d[2] * x * y + d[3] * (r2 + T(2) * x * x);
    *yd = y * radial + d[2] * (r2 + T(2) * y * y) + T(2) * d[3] * x * y;
  } else if (model == DistortionModel::kEquidistant) {
    const T r2 = x * x + y * y;
    if (r2 < T(1e-16)) {  // theta_d / r -> 1 as r -> 0
      *xd = x;
      *yd = y;
      return;
    }
    const T r = sqrt(r2);
    const T theta = atan(r);
    const T t2 = theta * theta;
    const T theta_d = theta * (T(1) + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
    const T s = theta_d / r;
    *xd = s * x;
    *yd = s * y;
  } else {
    *xd = x;
    *yd = y;
  }
}

/// Full projection generic in the scalar type. k = fx fy cx cy; d as distort_generic.
/// Returns false for points not in front of the camera.
template <typename T>
bool project_generic(DistortionModel model, const T* k, const T* d, const T* p, T* uv) {
  if (!(p[2] > T(PinholeCamera::kMinDepthM))) return false;
  const T x = p[0] / p[2];
  const T y = p[1] / p[2];
  T xd, yd;
  distort_generic(model, d, x, y, &xd, &yd);
  uv[0] = k[0] * xd + k[2];
  uv[1] = k[1] * yd + k[3];
  return true;
}

}  // namespace rgbdt::core
