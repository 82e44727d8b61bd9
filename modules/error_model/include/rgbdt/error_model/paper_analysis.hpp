#pragma once
/// \file
/// The closed-form coloring-error analysis of the paper (Sec. 4.3), as functions.
///
/// The paper looks only at the image x coordinate of a pinhole camera without distortion
/// and asks at which depth Z an error stops moving a projection by one pixel (Eq. (9),
/// (14)) or how large the pixel error from an extrinsic error is (Eq. (19), (25)).
/// These are kept for comparison with the paper's numbers; error_propagation.hpp holds the
/// general first-order model (all sources, both image axes, any pixel, metric distances).
///
/// Errata found while implementing (each checked by a unit test):
/// - Eq. (14) as printed, Z^2 + Z (fx dx + dfx X + dz) - (dz fx X + dz dfx X) = 0 with
///   dx = dz, has the largest root 3.337728 m for fx = 1335.054, dfx = 2, dz = 0.02, X = 5
///   and 1.073105 m for the thermal camera (fx = 417.20215, dfx = 6), not the paper's
///   4.304037 m and 3.524249 m. The paper's numbers are Eq. (9) solved with fx replaced by
///   fx + dfx: intrinsics_depth_m() computes that; printed_eq14_depth_m() the printed form.
/// - Eq. (19) is printed as (fx X cos dtheta - Z Y sin dtheta - fx X) / Z; the "Z Y" term
///   is not dimensionally a pixel. Eq. (18) with theta = 0 gives
///   (fx X cos dtheta - fx Y sin dtheta - fx X) / Z, which is what direct projection gives
///   and what rotation_pixel_error_px() returns.
/// - Eq. (23) writes fy where Eq. (21) and (25) use fx; fx is meant.

namespace rgbdt::error_model {

/// Eq. (9): the largest root Z of Z^2 + Z (dz + fx dz) - fx X dz = 0, i.e. the depth [m]
/// beyond which a LIDAR error dz (with dx = dz, as the paper assumes) moves the projection
/// of a point at lateral coordinate X by less than one pixel.
/// fx = 1335.054, dz = 0.02, X = 5 -> 4.303249 m; fx = 417.20215 -> 3.512751 m.
/// Throws std::invalid_argument unless fx_px > 0, lidar_noise_m > 0 and x_m > 0.
double lidar_noise_depth_m(double fx_px, double lidar_noise_m, double x_m = 5.0);

/// The paper-compatible form of Eq. (14): Eq. (9) with fx replaced by fx + dfx, which is
/// how the paper's numbers were obtained (fx = 1335.054, dfx = 2 -> 4.304037 m;
/// fx = 417.20215, dfx = 6 -> 3.524249 m). Requires fx_px + fx_error_px > 0.
double intrinsics_depth_m(double fx_px, double fx_error_px, double lidar_noise_m,
                          double x_m = 5.0);

/// Eq. (14) exactly as printed (largest root; dx = lidar_noise_m as in Eq. (8)). Kept to
/// document the erratum: it gives 3.337728 m and 1.073105 m for the paper's examples.
/// Throws std::invalid_argument if the equation has no positive root.
double printed_eq14_depth_m(double fx_px, double fx_error_px, double lidar_noise_m,
                            double x_m = 5.0);

/// Eq. (19) in its dimensionally consistent form (from Eq. (18), theta = 0): the x pixel
/// error x^p - x^g [px] of the point (X, Y, Z) [m, camera frame] when the rotation about
/// the optical axis is off by rotation_error_rad. Throws std::invalid_argument if z_m <= 0.
double rotation_pixel_error_px(double fx_px, double x_m, double y_m, double z_m,
                               double rotation_error_rad);

/// Eq. (25): the x pixel error fx dtx / (Z + tz) [px] of a point at depth z_m [m, LIDAR
/// frame] from a translation error dtx [m] (exact when dtz = 0, Eq. (24) drops dtz).
/// Throws std::invalid_argument if z_m + tz_m <= 0.
double translation_pixel_error_px(double fx_px, double z_m, double tz_m,
                                  double translation_error_x_m);

}  // namespace rgbdt::error_model
