#pragma once
/// \file
/// The coloring-error setup of the paper (Sec. 4.4, Fig. 11-12, Tables 2-3): a white card
/// in front of a black cloth, scanned by the LIDAR and coloured from a camera image with a
/// calibrated extrinsic. Wrong colours appear as a band along the card's edges; the paper
/// measured its width by hand in CloudCompare, this measures it automatically.
///
/// Measurement (measure_card_band):
///  0. the ground plane (RANSAC on near-horizontal planes) is removed: a vertical plane cuts
///     a strip of ground that can hold more points than a distant card;
///  1. geometry: the largest upright plane (RANSAC + least squares) and the largest among the
///     points off it are the cloth and the card, the nearer one being the card. Points on
///     neither (between them) are LIDAR mixed pixels at the card's edges and are ignored;
///  2. every point is moved along its LIDAR ray onto the card plane (so card and cloth points
///     have the same density there) and expressed in card coordinates: x to the right and
///     y up as seen from the LIDAR, origin at the card's centre;
///  3. colour class: card-coloured when the sampled intensity is on the card's side of the
///     midpoint between the median card and the median cloth intensity around the card
///     (the card may be the darker one, e.g. in a thermal image at night);
///  4. for each edge, the points in a strip across it (away from the corners) whose colour
///     class disagrees with their geometric class are counted. A colour pattern shifted by d
///     across an edge mis-colours on average d * length * density points, so the band width
///     is that count / (density * edge length), the density coming from the local sampling
///     lattice: unbiased even when d is smaller than the point spacing (which is ~6.5 cm at
///     15 m for 0.25 deg beams).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::error_model {

/// A grey image (row-major, any intensity scale) to sample point colours from.
struct GrayImage {
  int width = 0;
  int height = 0;
  std::vector<float> pixels;  ///< width * height values, row by row
  float at(int u, int v) const { return pixels[static_cast<std::size_t>(v) * width + u]; }
};

/// Nearest-pixel colouring: the intensity of the pixel each point projects to, NaN for
/// points behind the camera or outside the image. (No occlusion test: rgbdt_map does that;
/// here it would hide the very errors being measured.) Throws std::invalid_argument when
/// the image size does not match the camera or the pixel buffer.
std::vector<double> sample_point_intensities(const std::vector<Eigen::Vector3d>& points_lidar,
                                             const core::PinholeCamera& camera,
                                             const Eigen::Isometry3d& T_camera_lidar,
                                             const GrayImage& image);

struct CardBandOptions {
  /// Points within this distance of the card plane are on the card [m]. Must exceed the
  /// LIDAR noise (~3 sigma) and stay below the card-to-cloth gap.
  double card_plane_tolerance_m = 0.08;
  /// Half-width of the strip across each edge in which mis-coloured points are counted [m];
  /// larger than the largest band expected, smaller than half the card.
  double edge_strip_m = 0.25;
  /// Length cut off both ends of each edge so that the perpendicular edges' bands are not
  /// counted [m].
  double corner_margin_m = 0.15;
  int ransac_iterations = 300;  ///< plane hypotheses tried per colour class
  unsigned seed = 1;            ///< RANSAC random seed (results are deterministic)
  /// Fill CardBandMeasurement::points (for plots like the paper's Fig. 11-12).
  bool keep_points = false;
  std::string validate() const;  ///< empty when valid, else the reason
};

/// How a point near the card was classified.
enum class CardPointClass {
  kCard,                 ///< on the card, card-coloured
  kBackground,           ///< on the cloth, cloth-coloured
  kCardMiscoloured,      ///< on the card, cloth-coloured
  kBackgroundMiscoloured,  ///< on the cloth, card-coloured
  kMixed,                ///< between card and cloth (LIDAR mixed pixel), ignored
};

struct CardPoint {
  Eigen::Vector2d xy_m;  ///< card coordinates (along the LIDAR ray onto the card plane) [m]
  double intensity = 0.0;
  CardPointClass label = CardPointClass::kCard;
};

/// One card edge.
struct EdgeBand {
  std::string name;           ///< "left", "right", "bottom", "top" (seen from the LIDAR)
  double width_m = 0.0;       ///< mis-coloured band width across the edge [m]
  double inward_m = 0.0;      ///< part of it on the card (card points coloured dark) [m]
  double outward_m = 0.0;     ///< part of it beyond the card (background coloured bright) [m]
  int miscoloured_points = 0;
  int strip_points = 0;
  double length_m = 0.0;      ///< edge length the count was taken over [m]
};

struct CardBandMeasurement {
  Eigen::Vector3d card_centre_lidar = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Vector3d card_normal_lidar = Eigen::Vector3d::Zero();  ///< towards the LIDAR
  Eigen::Vector3d card_x_lidar = Eigen::Vector3d::Zero();       ///< right, seen from the LIDAR
  Eigen::Vector3d card_y_lidar = Eigen::Vector3d::Zero();       ///< up
  Eigen::Vector2d card_size_m = Eigen::Vector2d::Zero();        ///< extent of the card points
  double card_range_m = 0.0;  ///< distance from the LIDAR origin to the card centre [m]
  double density_per_m2 = 0.0;  ///< card points per square metre of card
  double intensity_threshold = 0.0;  ///< split between card and cloth colours
  bool card_is_bright = true;        ///< the card's colour class (thermal: may be dark)
  int card_points = 0, background_points = 0, coloured_points = 0;
  int mixed_points = 0;  ///< points between card and cloth (LIDAR mixed pixels), ignored
  int ground_points = 0;  ///< points on the ground plane, removed before anything else
  std::array<EdgeBand, 4> edges;  ///< left, right, bottom, top
  /// Card extent in card coordinates [m] (x0, x1, y0, y1: extreme card points).
  double x0_m = 0.0, x1_m = 0.0, y0_m = 0.0, y1_m = 0.0;
  /// The coloured points around the card, when CardBandOptions::keep_points.
  std::vector<CardPoint> points;
  double band_x_m = 0.0;  ///< mean band of the left and right edges (Table 2's x) [m]
  double band_y_m = 0.0;  ///< mean band of the bottom and top edges (Table 2's y) [m]
};

/// Measures the mis-coloured band. `intensities` has one value per point (NaN = not
/// coloured). Throws std::invalid_argument on size mismatch or invalid options, and
/// rgbdt::core::Error when no card can be found (no upright plane in either colour class,
/// too few points on it).
CardBandMeasurement measure_card_band(const std::vector<Eigen::Vector3d>& points_lidar,
                                      const std::vector<double>& intensities,
                                      const CardBandOptions& options = {});

/// Where the colour of a surface point comes from when it is coloured with an estimated
/// calibration but the image was taken with the true one: the point P [LIDAR frame] is
/// projected with (camera_estimated, T_estimated); that pixel shows, through the true
/// camera, the surface point X on the plane through P with normal plane_normal_lidar.
/// Returns X - P [m, LIDAR frame]. Its components across a card edge are the band widths
/// a perfect measurement would find. Throws std::invalid_argument when P is behind a camera.
Eigen::Vector3d colour_source_offset(const Eigen::Vector3d& point_lidar,
                                     const Eigen::Vector3d& plane_normal_lidar,
                                     const core::PinholeCamera& camera_true,
                                     const Eigen::Isometry3d& T_camera_lidar_true,
                                     const core::PinholeCamera& camera_estimated,
                                     const Eigen::Isometry3d& T_camera_lidar_estimated);

}  // namespace rgbdt::error_model
