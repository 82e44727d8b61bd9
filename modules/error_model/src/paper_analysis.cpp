#include "rgbdt/error_model/paper_analysis.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace rgbdt::error_model {
namespace {

void require_positive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    std::ostringstream os;
    os << name << " = " << value << ": expected a finite value > 0";
    throw std::invalid_argument(os.str());
  }
}

/// Largest real root of z^2 + b z + c = 0, or NaN when there is none.
double largest_root(double b, double c) {
  const double discriminant = b * b - 4.0 * c;
  if (discriminant < 0.0) return std::nan("");
  // The larger root is (-b + sqrt(D)) / 2. For b > 0 that form cancels; 2c / (-b - sqrt(D))
  // is the same root without the cancellation.
  const double s = std::sqrt(discriminant);
  return b > 0.0 ? (2.0 * c) / (-b - s) : 0.5 * (-b + s);
}

}  // namespace

double lidar_noise_depth_m(double fx_px, double lidar_noise_m, double x_m) {
  require_positive(fx_px, "fx_px");
  require_positive(lidar_noise_m, "lidar_noise_m");
  require_positive(x_m, "x_m");
  // Eq. (9): Z^2 + Z (dz + fx dz) - fx X dz = 0; c < 0 so the larger root is positive.
  const double dz = lidar_noise_m;
  return largest_root(dz + fx_px * dz, -fx_px * x_m * dz);
}

double intrinsics_depth_m(double fx_px, double fx_error_px, double lidar_noise_m, double x_m) {
  if (!std::isfinite(fx_error_px)) throw std::invalid_argument("fx_error_px is not finite");
  if (!(fx_px + fx_error_px > 0.0)) {
    std::ostringstream os;
    os << "fx_px + fx_error_px = " << fx_px + fx_error_px << ": expected > 0";
    throw std::invalid_argument(os.str());
  }
  return lidar_noise_depth_m(fx_px + fx_error_px, lidar_noise_m, x_m);
}

double printed_eq14_depth_m(double fx_px, double fx_error_px, double lidar_noise_m, double x_m) {
  require_positive(fx_px, "fx_px");
  require_positive(lidar_noise_m, "lidar_noise_m");
  require_positive(x_m, "x_m");
  const double dz = lidar_noise_m;
  const double dx = lidar_noise_m;  // the assumption of Eq. (8)
  // Eq. (14): Z^2 + Z (fx dx + dfx X + dz) - (dz fx X + dz dfx X) = 0.
  const double root = largest_root(fx_px * dx + fx_error_px * x_m + dz,
                                   -(dz * fx_px * x_m + dz * fx_error_px * x_m));
  if (!(root > 0.0)) {
    std::ostringstream os;
    os << "printed Eq. (14) has no positive root for fx = " << fx_px << ", dfx = " << fx_error_px;
    throw std::invalid_argument(os.str());
  }
  return root;
}

double rotation_pixel_error_px(double fx_px, double x_m, double y_m, double z_m,
                               double rotation_error_rad) {
  require_positive(z_m, "z_m");
  // Eq. (18) with theta = 0 (Eq. (19) corrected: fx Y sin instead of Z Y sin).
  return (fx_px * x_m * std::cos(rotation_error_rad) - fx_px * y_m * std::sin(rotation_error_rad) -
          fx_px * x_m) /
         z_m;
}

double translation_pixel_error_px(double fx_px, double z_m, double tz_m,
                                  double translation_error_x_m) {
  require_positive(z_m + tz_m, "z_m + tz_m");
  return fx_px * translation_error_x_m / (z_m + tz_m);  // Eq. (25)
}

}  // namespace rgbdt::error_model
