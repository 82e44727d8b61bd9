#include "rgbdt/error_model/error_propagation.hpp"

#include <ceres/jet.h>
#include <ceres/rotation.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

namespace rgbdt::error_model {
namespace {

// Parameter layout of the Jacobian: point (LIDAR frame), fx fy cx cy, 5 distortion
// coefficients (padded), extrinsics 6-vector.
constexpr int kPoint = 0;
constexpr int kIntrinsics = 3;
constexpr int kDistortion = 7;
constexpr int kExtrinsics = 12;
constexpr int kNumParameters = 18;
using Jet = ceres::Jet<double, kNumParameters>;

/// Pixel of a LIDAR point under intrinsics k, d and extrinsics parameters v (the meaning
/// of v depends on the perturbation convention; R0, t0 is the nominal T_camera_lidar used by
/// kLeft). Returns false behind the camera.
template <typename T>
bool project_lidar_point(core::DistortionModel model, ExtrinsicsPerturbation perturbation,
                         const Eigen::Isometry3d& T_camera_lidar, const T* p_lidar, const T* k,
                         const T* d, const T* v, T* uv) {
  T p_camera[3];
  if (perturbation == ExtrinsicsPerturbation::kVector6) {
    ceres::AngleAxisRotatePoint(v, p_lidar, p_camera);
  } else {
    const Eigen::Matrix3d& R = T_camera_lidar.linear();
    const Eigen::Vector3d& t = T_camera_lidar.translation();
    T p_nominal[3];
    for (int i = 0; i < 3; ++i) {
      p_nominal[i] = T(t[i]) + T(R(i, 0)) * p_lidar[0] + T(R(i, 1)) * p_lidar[1] + T(R(i, 2)) * p_lidar[2];
    }
    ceres::AngleAxisRotatePoint(v, p_nominal, p_camera);
  }
  for (int i = 0; i < 3; ++i) p_camera[i] += v[3 + i];
  return core::project_generic(model, k, d, p_camera, uv);
}

/// Tilt angle, range and beam angle of a LIDAR point under core::TiltRig's geometry.
struct BeamGeometry {
  double tilt_rad = 0.0;
  double range_m = 0.0;
  double beam_angle_rad = 0.0;
};

Eigen::Matrix3d rotation_y(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

double wrap_angle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

BeamGeometry solve_beam_geometry(const core::TiltRig& rig, const Eigen::Vector3d& p) {
  // The scan plane at tilt phi: {q : (Ry(-phi) q - t) . n = 0}, n = R_axis_scanner e_z.
  // Ry(-phi) p = (c px - s pz, py, s px + c pz), so A cos(phi) + B sin(phi) = D.
  const Eigen::Vector3d n = rig.T_axis_scanner.linear().col(2);
  const Eigen::Vector3d t = rig.T_axis_scanner.translation();
  const double a = p.x() * n.x() + p.z() * n.z();
  const double b = p.x() * n.z() - p.z() * n.x();
  const double d = t.dot(n) - p.y() * n.y();
  const double radius = std::hypot(a, b);
  if (radius < 1e-12 || std::abs(d) > radius) {
    std::ostringstream os;
    os << "LIDAR point (" << p.transpose() << ") cannot lie in the scan plane at any tilt angle "
       << "of the rig (mount normal " << n.transpose() << ")";
    throw std::invalid_argument(os.str());
  }
  const double alpha = std::atan2(b, a);
  const double delta = std::acos(std::clamp(d / radius, -1.0, 1.0));
  const double phi1 = wrap_angle(alpha + delta), phi2 = wrap_angle(alpha - delta);
  BeamGeometry g;
  g.tilt_rad = std::abs(phi1) <= std::abs(phi2) ? phi1 : phi2;  // the nearest tilt
  const Eigen::Vector3d s = rig.T_axis_scanner.inverse() * (rotation_y(-g.tilt_rad) * p);
  g.range_m = std::hypot(s.x(), s.y());
  g.beam_angle_rad = std::atan2(s.y(), s.x());
  return g;
}

Eigen::Vector3d beam_point(const core::TiltRig& rig, const BeamGeometry& g) {
  return rig.T_lidar_scanner(g.tilt_rad) *
         Eigen::Vector3d(g.range_m * std::cos(g.beam_angle_rad), g.range_m * std::sin(g.beam_angle_rad), 0.0);
}

/// A square root S of a symmetric positive semi-definite matrix (C = S S^T).
Eigen::MatrixXd covariance_root(const Eigen::MatrixXd& covariance) {
  if (covariance.size() == 0) return covariance;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(covariance);
  return eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

std::string psd_problem(const Eigen::MatrixXd& m, const std::string& name) {
  if (m.size() == 0) return {};
  std::ostringstream os;
  if (!m.allFinite()) {
    os << name << " has non-finite entries";
    return os.str();
  }
  const double scale = std::max(m.cwiseAbs().maxCoeff(), 1e-300);
  if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    os << name << " is not symmetric";
    return os.str();
  }
  const double min_eigen = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).eigenvalues().minCoeff();
  if (min_eigen < -1e-9 * scale) {
    os << name << " is not positive semi-definite (smallest eigenvalue " << min_eigen << ")";
    return os.str();
  }
  return {};
}

/// Surface axes for a normal: x = camera x projected onto the surface, y completes it
/// (the camera y axis for a fronto-parallel surface).
void surface_axes(const Eigen::Vector3d& n, Eigen::Vector3d* x, Eigen::Vector3d* y) {
  Eigen::Vector3d ex = Eigen::Vector3d::UnitX() - n.dot(Eigen::Vector3d::UnitX()) * n;
  if (ex.norm() < 1e-6) ex = Eigen::Vector3d::UnitY() - n.dot(Eigen::Vector3d::UnitY()) * n;
  *x = ex.normalized();
  Eigen::Vector3d ey = Eigen::Vector3d::UnitY() - n.dot(Eigen::Vector3d::UnitY()) * n - x->dot(Eigen::Vector3d::UnitY()) * *x;
  *y = ey.norm() < 1e-6 ? Eigen::Vector3d(n.cross(*x)) : Eigen::Vector3d(ey.normalized());
}

Eigen::Matrix2d sample_covariance(const std::vector<Eigen::Vector2d>& samples) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& s : samples) mean += s;
  mean /= static_cast<double>(samples.size());
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (const auto& s : samples) c += (s - mean) * (s - mean).transpose();
  return c / static_cast<double>(samples.size() - 1);
}

double sqrt_nonneg(double v) { return std::sqrt(std::max(v, 0.0)); }

}  // namespace

const char* to_string(Source source) {
  switch (source) {
    case Source::kLidar: return "lidar";
    case Source::kIntrinsics: return "intrinsics";
    case Source::kRotation: return "rotation";
    case Source::kTranslation: return "translation";
    case Source::kTotal: return "total";
  }
  return "unknown";
}

const char* display_name(Source source) {
  switch (source) {
    case Source::kLidar: return "LIDAR noise";
    case Source::kIntrinsics: return "intrinsics";
    case Source::kRotation: return "rotation";
    case Source::kTranslation: return "translation";
    case Source::kTotal: return "total";
  }
  return "unknown";
}

double SourceError::pixel_sigma_u_px() const { return sqrt_nonneg(pixel_covariance(0, 0)); }
double SourceError::pixel_sigma_v_px() const { return sqrt_nonneg(pixel_covariance(1, 1)); }
double SourceError::pixel_rms_px() const { return sqrt_nonneg(pixel_covariance.trace()); }
double SourceError::surface_sigma_x_m() const { return sqrt_nonneg(surface_covariance(0, 0)); }
double SourceError::surface_sigma_y_m() const { return sqrt_nonneg(surface_covariance(1, 1)); }
double SourceError::surface_rms_m() const { return sqrt_nonneg(surface_covariance.trace()); }

std::string LidarNoise::validate() const {
  std::ostringstream os;
  if (!(range_sigma_m >= 0.0) || !std::isfinite(range_sigma_m)) {
    os << "range_sigma_m = " << range_sigma_m << ": expected a finite value >= 0";
  } else if (!(beam_angle_sigma_rad >= 0.0) || !std::isfinite(beam_angle_sigma_rad)) {
    os << "beam_angle_sigma_rad = " << beam_angle_sigma_rad << ": expected a finite value >= 0";
  } else if (!(tilt_angle_sigma_rad >= 0.0) || !std::isfinite(tilt_angle_sigma_rad)) {
    os << "tilt_angle_sigma_rad = " << tilt_angle_sigma_rad << ": expected a finite value >= 0";
  }
  return os.str();
}

std::string ErrorSources::validate() const {
  if (auto why = intrinsics.validate(); !why.empty()) return "intrinsics: " + why;
  if (auto why = lidar.validate(); !why.empty()) return "lidar: " + why;
  const int n = static_cast<int>(intrinsics_covariance.rows());
  const int full = 4 + core::distortion_size(intrinsics.model);
  if (intrinsics_covariance.size() != 0 &&
      (intrinsics_covariance.cols() != n || (n != 4 && n != full))) {
    std::ostringstream os;
    os << "intrinsics_covariance is " << intrinsics_covariance.rows() << "x" << intrinsics_covariance.cols()
       << ": expected 4x4 (fx fy cx cy) or " << full << "x" << full << " (with the "
       << core::to_string(intrinsics.model) << " coefficients)";
    return os.str();
  }
  if (auto why = psd_problem(intrinsics_covariance, "intrinsics_covariance"); !why.empty()) return why;
  if (auto why = psd_problem(extrinsics_covariance, "extrinsics_covariance"); !why.empty()) return why;
  if (!T_camera_lidar.matrix().allFinite()) return "T_camera_lidar has non-finite entries";
  if (auto why = rig.scanner.validate(); !why.empty()) return "rig: " + why;
  return {};
}

namespace {
core::PinholeCamera checked_camera(const ErrorSources& sources) {
  if (auto why = sources.validate(); !why.empty()) throw std::invalid_argument("ErrorSources: " + why);
  return core::PinholeCamera(sources.intrinsics);
}
}  // namespace

ColoringErrorModel::ColoringErrorModel(const ErrorSources& sources)
    : sources_(sources), camera_(checked_camera(sources)), v0_(core::to_vector6(sources.T_camera_lidar)) {
  const auto& d = sources_.intrinsics.distortion;
  for (std::size_t i = 0; i < d.size() && i < distortion_.size(); ++i) distortion_[i] = d[i];
}

Eigen::Matrix3d ColoringErrorModel::lidar_point_covariance(const Eigen::Vector3d& point_lidar) const {
  const core::TiltRig& rig = sources_.rig;
  const BeamGeometry g = solve_beam_geometry(rig, point_lidar);
  const Eigen::Matrix3d R = rotation_y(g.tilt_rad) * rig.T_axis_scanner.linear();
  const double c = std::cos(g.beam_angle_rad), s = std::sin(g.beam_angle_rad);
  const Eigen::Vector3d d_range = R * Eigen::Vector3d(c, s, 0.0);
  const Eigen::Vector3d d_beam = R * Eigen::Vector3d(-s, c, 0.0) * g.range_m;
  const Eigen::Vector3d d_tilt = Eigen::Vector3d::UnitY().cross(point_lidar);  // d(Ry(phi) q)/dphi
  const LidarNoise& noise = sources_.lidar;
  return std::pow(noise.range_sigma_m, 2) * d_range * d_range.transpose() +
         std::pow(noise.beam_angle_sigma_rad, 2) * d_beam * d_beam.transpose() +
         std::pow(noise.tilt_angle_sigma_rad, 2) * d_tilt * d_tilt.transpose();
}

ColoringErrorPrediction ColoringErrorModel::predict(const Eigen::Vector2d& pixel, double depth_m,
                                                    const Eigen::Vector3d& normal_camera) const {
  if (!(depth_m > 0.0) || !std::isfinite(depth_m)) {
    std::ostringstream os;
    os << "depth_m = " << depth_m << ": expected a finite depth > 0";
    throw std::invalid_argument(os.str());
  }
  const Eigen::Vector3d point_camera = depth_m * camera_.unproject(pixel);
  return predict_point(sources_.T_camera_lidar.inverse() * point_camera, normal_camera);
}

ColoringErrorPrediction ColoringErrorModel::predict_point(const Eigen::Vector3d& point_lidar,
                                                          const Eigen::Vector3d& normal_camera) const {
  ColoringErrorPrediction out;
  out.point_lidar = point_lidar;
  out.point_camera = sources_.T_camera_lidar * point_lidar;
  if (!(normal_camera.norm() > 0.0) || !normal_camera.allFinite()) {
    throw std::invalid_argument("normal_camera: expected a finite non-zero vector");
  }
  out.normal_camera = normal_camera.normalized();
  surface_axes(out.normal_camera, &out.surface_x_camera, &out.surface_y_camera);

  // Exact Jacobian of the pixel with respect to all 18 parameters.
  Jet p[3], k[4], d[5], v[6], uv[2];
  for (int i = 0; i < 3; ++i) p[i] = Jet(point_lidar[i], kPoint + i);
  const auto& K = sources_.intrinsics;
  const double k0[4] = {K.fx, K.fy, K.cx, K.cy};
  for (int i = 0; i < 4; ++i) k[i] = Jet(k0[i], kIntrinsics + i);
  for (int i = 0; i < 5; ++i) d[i] = Jet(distortion_[i], kDistortion + i);
  const bool vector6 = sources_.extrinsics_perturbation == ExtrinsicsPerturbation::kVector6;
  for (int i = 0; i < 6; ++i) v[i] = Jet(vector6 ? v0_[i] : 0.0, kExtrinsics + i);
  if (!project_lidar_point(K.model, sources_.extrinsics_perturbation, sources_.T_camera_lidar, p, k, d, v, uv)) {
    std::ostringstream os;
    os << "point (" << point_lidar.transpose() << ") [LIDAR frame] is behind the camera";
    throw std::invalid_argument(os.str());
  }
  out.pixel = Eigen::Vector2d(uv[0].a, uv[1].a);
  Eigen::Matrix<double, 2, kNumParameters> J;
  J.row(0) = uv[0].v.transpose();
  J.row(1) = uv[1].v.transpose();

  // Back-projection of a pixel displacement onto the surface (true calibration):
  // X(u) = s d(u), s = n.P / n.d, so dX/du = s (I - d n^T / n.d) dd/du.
  const Eigen::Vector3d ray = camera_.unproject(out.pixel);
  const Eigen::Vector3d& n = out.normal_camera;
  const double n_dot_ray = n.dot(ray);
  if (std::abs(n_dot_ray) < 1e-3 * ray.norm()) {
    throw std::invalid_argument("the surface is seen edge-on from the camera (normal . ray ~ 0)");
  }
  Eigen::Matrix2d J_distort;
  camera_.distort(ray.head<2>(), &J_distort);
  Eigen::Matrix<double, 3, 2> d_ray_d_pixel = Eigen::Matrix<double, 3, 2>::Zero();
  d_ray_d_pixel.topRows<2>() = J_distort.inverse() * Eigen::Vector2d(1.0 / K.fx, 1.0 / K.fy).asDiagonal();
  const double scale = n.dot(out.point_camera) / n_dot_ray;
  const Eigen::Matrix<double, 3, 2> d_surface_d_pixel =
      scale * (Eigen::Matrix3d::Identity() - ray * n.transpose() / n_dot_ray) * d_ray_d_pixel;
  Eigen::Matrix<double, 2, 3> S;
  S.row(0) = out.surface_x_camera.transpose();
  S.row(1) = out.surface_y_camera.transpose();
  const Eigen::Matrix2d B = S * d_surface_d_pixel;

  // Per-source pixel covariances.
  auto& src = out.sources;
  const Eigen::Matrix<double, 2, 3> J_point = J.middleCols<3>(kPoint);
  src[static_cast<int>(Source::kLidar)].pixel_covariance = J_point * lidar_point_covariance(point_lidar) * J_point.transpose();
  const Eigen::MatrixXd& C_k = sources_.intrinsics_covariance;
  if (C_k.size() != 0) {
    const int m = static_cast<int>(C_k.rows());
    const Eigen::MatrixXd J_k = J.middleCols(kIntrinsics, m);  // fx fy cx cy then distortion
    src[static_cast<int>(Source::kIntrinsics)].pixel_covariance = J_k * C_k * J_k.transpose();
  }
  const Eigen::Matrix<double, 2, 6> J_v = J.middleCols<6>(kExtrinsics);
  const core::Matrix6d& C_v = sources_.extrinsics_covariance;
  src[static_cast<int>(Source::kRotation)].pixel_covariance =
      J_v.leftCols<3>() * C_v.topLeftCorner<3, 3>() * J_v.leftCols<3>().transpose();
  src[static_cast<int>(Source::kTranslation)].pixel_covariance =
      J_v.rightCols<3>() * C_v.bottomRightCorner<3, 3>() * J_v.rightCols<3>().transpose();
  src[static_cast<int>(Source::kTotal)].pixel_covariance =
      src[static_cast<int>(Source::kLidar)].pixel_covariance +
      src[static_cast<int>(Source::kIntrinsics)].pixel_covariance + J_v * C_v * J_v.transpose();
  for (auto& e : src) e.surface_covariance = B * e.pixel_covariance * B.transpose();
  return out;
}

ColoringErrorPrediction ColoringErrorModel::monte_carlo(const Eigen::Vector2d& pixel, double depth_m,
                                                        const Eigen::Vector3d& normal_camera, int samples,
                                                        std::uint64_t seed) const {
  if (samples < 2) {
    std::ostringstream os;
    os << "samples = " << samples << ": expected at least 2";
    throw std::invalid_argument(os.str());
  }
  // The nominal geometry, axes and true pixel come from the first-order prediction.
  ColoringErrorPrediction out = predict(pixel, depth_m, normal_camera);
  out.samples = samples;
  for (auto& e : out.sources) e = SourceError{};

  const auto& K = sources_.intrinsics;
  const BeamGeometry beam = solve_beam_geometry(sources_.rig, out.point_lidar);
  const Eigen::MatrixXd root_k = covariance_root(sources_.intrinsics_covariance);
  const Eigen::MatrixXd root_v = covariance_root(sources_.extrinsics_covariance);
  const Eigen::MatrixXd root_r = covariance_root(sources_.extrinsics_covariance.topLeftCorner<3, 3>());
  const Eigen::MatrixXd root_t = covariance_root(sources_.extrinsics_covariance.bottomRightCorner<3, 3>());
  const bool vector6 = sources_.extrinsics_perturbation == ExtrinsicsPerturbation::kVector6;
  const Eigen::Vector3d& n = out.normal_camera;
  const double n_dot_p = n.dot(out.point_camera);

  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gaussian = [&](const Eigen::MatrixXd& root) {
    Eigen::VectorXd z(root.cols());
    for (int i = 0; i < z.size(); ++i) z[i] = normal(rng);
    return Eigen::VectorXd(root * z);
  };

  for (int si = 0; si < kNumSources; ++si) {
    const auto source = static_cast<Source>(si);
    const bool all = source == Source::kTotal;
    std::vector<Eigen::Vector2d> pixel_errors, surface_errors;
    pixel_errors.reserve(samples);
    surface_errors.reserve(samples);
    int attempts = 0;
    while (static_cast<int>(pixel_errors.size()) < samples) {
      if (++attempts > 4 * samples) {
        throw std::invalid_argument("monte_carlo: most perturbed points fall behind the camera");
      }
      Eigen::Vector3d p = out.point_lidar;
      if (all || source == Source::kLidar) {
        BeamGeometry g = beam;
        g.range_m += sources_.lidar.range_sigma_m * normal(rng);
        g.beam_angle_rad += sources_.lidar.beam_angle_sigma_rad * normal(rng);
        g.tilt_rad += sources_.lidar.tilt_angle_sigma_rad * normal(rng);
        p = beam_point(sources_.rig, g);
      }
      double k[4] = {K.fx, K.fy, K.cx, K.cy};
      std::array<double, 5> d = distortion_;
      if ((all || source == Source::kIntrinsics) && root_k.size() != 0) {
        const Eigen::VectorXd dk = gaussian(root_k);
        for (int i = 0; i < dk.size(); ++i) (i < 4 ? k[i] : d[i - 4]) += dk[i];
      }
      core::Vector6d v = vector6 ? v0_ : core::Vector6d::Zero();
      if (all) v += gaussian(root_v);
      if (source == Source::kRotation) v.head<3>() += gaussian(root_r);
      if (source == Source::kTranslation) v.tail<3>() += gaussian(root_t);
      double uv[2];
      if (!project_lidar_point(K.model, sources_.extrinsics_perturbation, sources_.T_camera_lidar, p.data(), k,
                               d.data(), v.data(), uv)) {
        continue;
      }
      const Eigen::Vector2d pixel_error = Eigen::Vector2d(uv[0], uv[1]) - out.pixel;
      // The surface point the perturbed pixel shows (true calibration, true surface).
      const Eigen::Vector3d ray = camera_.unproject(Eigen::Vector2d(uv[0], uv[1]));
      const Eigen::Vector3d shown = (n_dot_p / n.dot(ray)) * ray;
      const Eigen::Vector3d offset = shown - out.point_camera;
      pixel_errors.push_back(pixel_error);
      surface_errors.emplace_back(offset.dot(out.surface_x_camera), offset.dot(out.surface_y_camera));
    }
    out.sources[si].pixel_covariance = sample_covariance(pixel_errors);
    out.sources[si].surface_covariance = sample_covariance(surface_errors);
  }
  return out;
}

double across_edge_sigma_m(const Eigen::Matrix2d& surface_covariance, const Eigen::Vector2d& edge_direction) {
  if (!(edge_direction.norm() > 0.0)) throw std::invalid_argument("edge_direction: expected a non-zero vector");
  const Eigen::Vector2d e = edge_direction.normalized();
  const Eigen::Vector2d across(-e.y(), e.x());
  return sqrt_nonneg(across.dot(surface_covariance * across));
}

}  // namespace rgbdt::error_model
