#pragma once
/// \file
/// Covariance of the camera-LIDAR extrinsics of Eq. (2), in the parametrisation of
/// core::to_vector6 ([rx ry rz tx ty tz], rad^2, m^2), honest about what the residuals of
/// the image edges cannot show.
///
/// The circle points of a hole are not measurements: they are sampled from one circle
/// (centre, normal, known radius) fitted to a few LIDAR edge points and the board plane. An
/// error of that circle moves all of its points together, and with one hole per view the
/// pose absorbs it completely (the residuals stay small while the pose is off). The
/// covariance therefore has these terms, all evaluated at the solution x with H = J^T J of
/// the plain point residuals:
///  - jacobian:   sigma^2 H^-1, sigma^2 = |r|^2 / (N - 6): independent image-edge noise.
///  - sandwich:   cluster-robust H^-1 (sum_h s_h s_h^T) H^-1 G / (G - 1), s_h = J_h^T r_h
///                the score of hole h (G holes in all): the correlation of the residuals
///                along one edge (G >= 2; else equal to `jacobian`).
///  - systematic: the LIDAR circle errors propagated through the minimiser,
///                H^-1 (sum_h B_h Sigma_h B_h^T) H^-1, B_h = sum_i J_i^T (d r_i / d p_i)
///                (d p_i / d theta_h), theta_h = (centre shift, tilt of the normal) of hole
///                h with covariance Sigma_h from LidarHoleSigma: what no view reveals about
///                itself.
///  - jackknife:  (V - 1) / V sum_v (x_-v - mean)(x_-v - mean)^T over the leave-one-view-out
///                solutions (V >= 3 views): the scatter the views actually show. Each
///                x_-v is one Gauss-Newton step from x on the other views' normal
///                equations (CovarianceOptions::jackknife_one_step).
///  - resampled:  with 1-2 views, (1/M) sum_m (x_m - x)(x_m - x)^T over M re-solves from x,
///                each on circles moved by one draw of every hole's LIDAR error: the
///                systematic term without its linearisation. Few views leave directions
///                that only the holes' normals or a lever of a few hole spacings constrain;
///                there a circle's error moves the pose far and along a curve (a rotation
///                of 10-20 deg about the board swings the translation by decimetres), which
///                the first-order term misses by 10-40x.
/// total = sandwich + systematic, raised (in every direction: the matrix whose quadratic
/// form is the larger) with >= 3 views to the jackknife, with fewer to sandwich + resampled.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "rgbdt/core/transform.hpp"

namespace rgbdt::extrinsics {

/// 1-sigma of one LIDAR hole circle.
struct LidarHoleSigma {
  double center_in_plane_m = 0.0;  ///< of the centre, per in-plane axis [m]
  double center_normal_m = 0.0;    ///< of the centre along the board normal [m]
  double tilt_rad = 0.0;           ///< of the normal, about each in-plane axis [rad]
};

/// The uncertainty of a detected hole from its detection.
///
/// In the plane, the centre's scatter part is sigma_e^2 (sum_i u_i u_i^T)^-1 (the larger
/// axis) with u_i the in-plane radial directions of the edge points and sigma_e the scatter
/// of |p - c| - r about its mean, never below the point spacing's quantisation
/// (spacing^2 / 12: the edge lies anywhere within one step of the last board point). Edge
/// points closer together than the beam footprint (twice the edge bias the view measured)
/// or the point spacing see the same stretch of edge, so the count is capped at the number
/// of such stretches around the hole. An edge error that varies slowly around the hole (a
/// point density that changes across it) moves the centre by its first Fourier order,
/// which the fit absorbs; with >= 36 edge points in all four quadrants the in-plane sigma
/// is at least the RMS coefficient of the radial residuals' Fourier orders 2-5 (fitted
/// with orders 0-5). Along the normal: the offset at the centre and the tilt of the
/// least-squares plane through the board points (their RMS distance to the plane is the
/// range noise along the normal).
///
/// On top of both, the beam footprint's systematic part: a return whose footprint straddles
/// an edge lies behind the board by a part of the footprint's depth spread, so the fitted
/// plane and the edges on the side facing away from the sensor carry an offset that does
/// not average out over points. It is modelled as 0.5 * edge_bias_m * sin(incidence) in the
/// plane and along the normal (incidence between the beam to the centre, from the sensor at
/// the origin, and the normal); docs/calibration.md shows where the 0.5 comes from. Throws
/// std::invalid_argument for fewer than 3 edge points or 3 board points.
LidarHoleSigma lidar_hole_sigma(const std::vector<Eigen::Vector3d>& edge_points,
                                const std::vector<Eigen::Vector3d>& board_points,
                                const Eigen::Vector3d& center, const Eigen::Vector3d& normal,
                                double radius_m, double edge_bias_m = 0.0, double point_spacing_m = 0.0);

struct CovarianceOptions {
  /// Per input view of align_edges (same order), per hole (the order of the view's
  /// lidar_centers, else of its circle points): the hole's LIDAR uncertainty, e.g. from
  /// lidar_hole_sigma(). A view without entries (or with a count that does not match its
  /// holes) uses default_range_sigma_m.
  std::vector<std::vector<LidarHoleSigma>> per_view;
  /// Without per-view entries: the LIDAR range noise [m], taken as the hole centre's
  /// 1-sigma on every axis and, over the hole radius, as the tilt of its normal.
  double default_range_sigma_m = 0.01;
  bool jackknife = true;  ///< leave-one-view-out with >= 3 used views
  /// Each leave-one-view-out solution as one Gauss-Newton step from the solution x on the
  /// normal equations of the other views at x (H - H_v, the other views' gradient), from one
  /// pass over the points; false: a Levenberg-Marquardt polish of the other views from x to
  /// convergence (a few passes each).
  bool jackknife_one_step = true;
  /// With 1-2 used views (no jackknife): re-solves on this many draws of the LIDAR circles'
  /// errors (0 = none).
  int resamples = 64;
  std::string validate() const;  ///< empty when valid, else the reason
};

/// The terms of the covariance (see the file comment), each 6x6 in to_vector6 order.
struct CovarianceTerms {
  core::Matrix6d jacobian = core::Matrix6d::Zero();
  core::Matrix6d sandwich = core::Matrix6d::Zero();
  core::Matrix6d systematic = core::Matrix6d::Zero();
  core::Matrix6d jackknife = core::Matrix6d::Zero();
  core::Matrix6d resampled = core::Matrix6d::Zero();
  core::Matrix6d total = core::Matrix6d::Zero();
  int num_views = 0;            ///< used views
  int num_holes = 0;            ///< hole clusters over the used views
  int holes_with_sigma = 0;     ///< of which have a LidarHoleSigma from the caller
  bool jackknife_used = false;  ///< >= 3 views and the leave-one-out solves ran
  bool resampled_used = false;  ///< < 3 views and the re-solves on perturbed circles ran
  bool valid = false;           ///< H full rank: every parameter observable
};

/// Mahalanobis distance squared e^T C^-1 e (the NEES of an error e under C); +infinity when
/// C is not positive definite.
double nees(const core::Vector6d& error, const core::Matrix6d& covariance);

/// The larger of two covariances in every direction: A + (B - A)_+ with (.)_+ the positive
/// part of the symmetric difference, so that v^T M v >= max(v^T A v, v^T B v) for all v.
core::Matrix6d covariance_max(const core::Matrix6d& A, const core::Matrix6d& B);

}  // namespace rgbdt::extrinsics
