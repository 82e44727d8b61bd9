#include "rgbdt/core/camera.hpp"

#include <Eigen/Dense>
#include <sstream>
#include <stdexcept>

namespace rgbdt::core {

std::string to_string(DistortionModel model) {
  switch (model) {
    case DistortionModel::kEquidistant: return "equidistant";
    case DistortionModel::kNone:
    case DistortionModel::kPlumbBob: return "plumb_bob";
  }
  return "plumb_bob";
}

DistortionModel distortion_model_from_string(const std::string& name) {
  if (name == "plumb_bob") return DistortionModel::kPlumbBob;
  if (name == "equidistant" || name == "fisheye") return DistortionModel::kEquidistant;
  if (name == "none") return DistortionModel::kNone;
  throw std::invalid_argument("distortion model '" + name +
                              "' is not supported (expected plumb_bob or equidistant)");
}

int distortion_size(DistortionModel model) {
  switch (model) {
    case DistortionModel::kPlumbBob: return 5;
    case DistortionModel::kEquidistant: return 4;
    case DistortionModel::kNone: return 0;
  }
  return 0;
}

std::string CameraIntrinsics::validate() const {
  std::ostringstream os;
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide) {
    os << "image size " << width << "x" << height << " must be positive and at most "
       << kMaxImageSide << " px a side";
  } else if (!(fx > 0) || !(fy > 0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    os << "focal lengths fx=" << fx << " fy=" << fy << " must be positive and finite";
  } else if (!std::isfinite(cx) || !std::isfinite(cy)) {
    os << "principal point (" << cx << ", " << cy << ") must be finite";
  } else if (!(cx >= 0 && cx <= width && cy >= 0 && cy <= height)) {
    os << "principal point (" << cx << ", " << cy << ") must lie inside the " << width << "x"
       << height << " image";
  } else if (static_cast<int>(distortion.size()) > distortion_size(model) &&
             model != DistortionModel::kPlumbBob) {
    os << to_string(model) << " takes " << distortion_size(model) << " coefficients, got "
       << distortion.size();
  } else if (model == DistortionModel::kPlumbBob && distortion.size() > 5) {
    // ROS writes 5 for plumb_bob; OpenCV's 8-term rational model is not plumb_bob.
    for (size_t i = 5; i < distortion.size(); ++i) {
      if (distortion[i] != 0.0) {
        os << "plumb_bob takes 5 coefficients (k1 k2 p1 p2 k3); coefficient " << i + 1
           << " is " << distortion[i] << " (the rational model is not supported)";
        break;
      }
    }
  }
  for (double d : distortion) {
    if (!std::isfinite(d) && os.str().empty()) os << "distortion coefficient is not finite";
  }
  return os.str();
}

PinholeCamera::PinholeCamera(const CameraIntrinsics& intrinsics) : intrinsics_(intrinsics) {
  const std::string why = intrinsics_.validate();
  if (!why.empty()) throw std::invalid_argument("camera '" + intrinsics_.camera_name + "': " + why);
  const int n = std::min<int>(static_cast<int>(intrinsics_.distortion.size()), 5);
  for (int i = 0; i < n; ++i) d_[i] = intrinsics_.distortion[i];
  intrinsics_.distortion.resize(distortion_size(intrinsics_.model), 0.0);
  if (intrinsics_.model == DistortionModel::kNone) intrinsics_.model = DistortionModel::kPlumbBob;
}

Eigen::Vector2d PinholeCamera::distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* J) const {
  const double x = xy.x(), y = xy.y();
  Eigen::Vector2d out;
  distort_generic(intrinsics_.model, d_, x, y, &out.x(), &out.y());
  if (!J) return out;
  if (intrinsics_.model == DistortionModel::kPlumbBob) {
    const double k1 = d_[0], k2 = d_[1], p1 = d_[2], p2 = d_[3], k3 = d_[4];
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2);  // d radial / d r2
    (*J)(0, 0) = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x;
    (*J)(0, 1) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    (*J)(1, 0) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    (*J)(1, 1) = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x;
  } else if (intrinsics_.model == DistortionModel::kEquidistant) {
    const double r2 = x * x + y * y;
    if (r2 < 1e-16) {
      J->setIdentity();
      return out;
    }
    const double r = std::sqrt(r2);
    const double th = std::atan(r), t2 = th * th;
    const double poly = 1 + t2 * (d_[0] + t2 * (d_[1] + t2 * (d_[2] + t2 * d_[3])));
    const double theta_d = th * poly;
    const double dtheta_d = 1 + t2 * (3 * d_[0] + t2 * (5 * d_[1] + t2 * (7 * d_[2] + t2 * 9 * d_[3])));
    const double s = theta_d / r;
    // ds/dr = (dtheta_d/dtheta * dtheta/dr * r - theta_d) / r^2
    const double ds_dr = (dtheta_d / (1 + r2) * r - theta_d) / r2;
    (*J)(0, 0) = s + x * ds_dr * x / r;
    (*J)(0, 1) = x * ds_dr * y / r;
    (*J)(1, 0) = y * ds_dr * x / r;
    (*J)(1, 1) = s + y * ds_dr * y / r;
  } else {
    J->setIdentity();
  }
  return out;
}

bool PinholeCamera::project(const Eigen::Vector3d& p, Eigen::Vector2d* pixel,
                            Eigen::Matrix<double, 2, 3>* J_point) const {
  if (!(p.z() > kMinDepthM)) return false;
  const double inv_z = 1.0 / p.z();
  const Eigen::Vector2d xy(p.x() * inv_z, p.y() * inv_z);
  Eigen::Matrix2d Jd;
  const Eigen::Vector2d xyd = distort(xy, J_point ? &Jd : nullptr);
  if (pixel) {
    *pixel = {intrinsics_.fx * xyd.x() + intrinsics_.cx, intrinsics_.fy * xyd.y() + intrinsics_.cy};
  }
  if (J_point) {
    Eigen::Matrix<double, 2, 3> Jn;  // d(xy)/d(p)
    Jn << inv_z, 0, -p.x() * inv_z * inv_z, 0, inv_z, -p.y() * inv_z * inv_z;
    const Eigen::Matrix2d K = Eigen::Vector2d(intrinsics_.fx, intrinsics_.fy).asDiagonal();
    *J_point = K * Jd * Jn;
  }
  return true;
}

Eigen::Vector3d PinholeCamera::unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d target((pixel.x() - intrinsics_.cx) / intrinsics_.fx,
                               (pixel.y() - intrinsics_.cy) / intrinsics_.fy);
  Eigen::Vector2d xy = target;
  if (intrinsics_.model == DistortionModel::kEquidistant) {
    // Start from the exact inverse of the undistorted fisheye: r = tan(theta_d).
    const double rd = target.norm();
    if (rd > 1e-12 && rd < 1.5) xy = target * (std::tan(rd) / rd);
  }
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix2d J;
    const Eigen::Vector2d residual = distort(xy, &J) - target;
    if (residual.norm() < 1e-14) break;
    // The 2x2 Newton step by Cramer's rule; a singular J or a non-finite step stops here.
    const double det = J(0, 0) * J(1, 1) - J(0, 1) * J(1, 0);
    if (!(det != 0.0)) break;
    const Eigen::Vector2d step((J(1, 1) * residual.x() - J(0, 1) * residual.y()) / det,
                               (J(0, 0) * residual.y() - J(1, 0) * residual.x()) / det);
    if (!step.allFinite()) break;
    xy -= step;
    if (step.norm() < 1e-15) break;
  }
  return {xy.x(), xy.y(), 1.0};
}

bool PinholeCamera::in_image(const Eigen::Vector2d& px, double margin) const {
  // Pixel centres run 0..w-1; the image covers [-0.5, w-0.5).
  return px.x() >= -0.5 + margin && px.y() >= -0.5 + margin &&
         px.x() < intrinsics_.width - 0.5 - margin && px.y() < intrinsics_.height - 0.5 - margin;
}

}  // namespace rgbdt::core
