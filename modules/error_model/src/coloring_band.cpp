#include "rgbdt/error_model/coloring_band.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::error_model {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double distance(const Eigen::Vector3d& p) const { return normal.dot(p - point); }
};

Plane fit_plane_least_squares(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - centroid) * (p - centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  return Plane{eig.eigenvectors().col(0), centroid};  // smallest spread = normal
}

/// Upright planes (cards, cloths) have |normal z| <= kMaxUprightNormalZ; the ground has
/// |normal z| >= kMinGroundNormalZ.
constexpr double kMaxUprightNormalZ = 0.7;
constexpr double kMinGroundNormalZ = 0.9;
enum class PlaneKind { kUpright, kGround };
constexpr double kMinGroundDepthM = 0.3;   ///< the ground is at least this far below the LIDAR
constexpr double kMinGroundSpreadM = 2.0;  ///< 10-90 % spread of its points' horizontal range

/// The plane of the given kind with most inliers, refined by least squares; none if no
/// sample gives one.
std::optional<Plane> ransac_plane(const std::vector<Eigen::Vector3d>& points, double tolerance_m, int iterations,
                                  unsigned seed, PlaneKind kind = PlaneKind::kUpright) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  Plane best;
  std::size_t best_inliers = 0;
  for (int it = 0; it < iterations; ++it) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    const double nz = std::abs(n.normalized().z());
    if (kind == PlaneKind::kUpright ? nz > kMaxUprightNormalZ : nz < kMinGroundNormalZ) continue;
    const Plane plane{n.normalized(), a};
    std::size_t inliers = 0;
    for (const auto& p : points) inliers += std::abs(plane.distance(p)) <= tolerance_m;
    if (inliers > best_inliers) {
      best_inliers = inliers;
      best = plane;
    }
  }
  if (best_inliers < 3) return std::nullopt;
  std::vector<Eigen::Vector3d> inliers;
  for (const auto& p : points) {
    if (std::abs(best.distance(p)) <= tolerance_m) inliers.push_back(p);
  }
  return fit_plane_least_squares(inliers);
}

double quantile(std::vector<double> v, double q) {
  const std::size_t k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

/// The ground first: a vertical plane cuts a strip of it that can hold more points than a
/// distant card, so ground points must not take part in finding the card. Marks the points
/// on the ground (none when no plane looks like it); counts them and the coloured points in *m.
std::vector<char> find_ground(const std::vector<Eigen::Vector3d>& points_lidar,
                              const std::vector<double>& intensities,
                              const CardBandOptions& options, CardBandMeasurement* m) {
  const std::size_t n = points_lidar.size();
  std::vector<char> ground(n, 0);
  std::vector<Eigen::Vector3d> coloured;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isfinite(intensities[i])) coloured.push_back(points_lidar[i]);
  }
  m->coloured_points = static_cast<int>(coloured.size());
  const std::optional<Plane> floor =
      coloured.size() >= 20
          ? ransac_plane(coloured, 0.5 * options.card_plane_tolerance_m, options.ransac_iterations,
                         options.seed + 2, PlaneKind::kGround)
          : std::nullopt;
  // Only points within half the plane tolerance of the ground are removed: a card standing
  // close above the ground keeps the cloth points of its bottom band.
  // A horizontal plane through a scan line of card and cloth also holds many points; the
  // ground is below the sensor and its points spread over a wide range of distances.
  std::vector<double> floor_ranges;
  if (floor) {
    for (const auto& p : coloured) {
      if (std::abs(floor->distance(p)) <= options.card_plane_tolerance_m)
        floor_ranges.push_back(p.head<2>().norm());
    }
  }
  const bool below = floor && std::abs(floor->normal.dot(floor->point)) > kMinGroundDepthM &&
                     floor->point.z() < 0.0;
  const bool spread = floor_ranges.size() >= std::max<std::size_t>(20, coloured.size() / 20) &&
                      quantile(floor_ranges, 0.9) - quantile(floor_ranges, 0.1) > kMinGroundSpreadM;
  if (below && spread) {
    for (std::size_t i = 0; i < n; ++i) {
      if (std::abs(floor->distance(points_lidar[i])) <= 0.5 * options.card_plane_tolerance_m) {
        ground[i] = 1;
        ++m->ground_points;
      }
    }
  }
  return ground;
}

/// The card and cloth planes and every point in card coordinates with its geometric class.
struct CardGeometry {
  Plane card, cloth;                ///< normals towards the LIDAR
  Eigen::Vector3d x_axis, y_axis;   ///< of the card: x right and y up as seen from the LIDAR
  std::vector<Eigen::Vector2d> xy;  ///< where the point's LIDAR ray meets the card plane
  std::vector<int> geometry;        ///< 1 card, -1 background, 0 neither
  std::vector<char> between;        ///< between card and cloth (mixed pixels)
};

/// Geometry first, colour second: the largest upright plane and the largest one among the
/// points off it are the cloth and the card; the nearer one is the card. (Splitting by colour
/// first fails in thermal images, where the cloth's rim shows the sky and the pavement.)
/// Throws when there are not two such planes.
std::pair<Plane, Plane> find_card_and_cloth(const std::vector<Eigen::Vector3d>& points_lidar,
                                            const std::vector<double>& intensities,
                                            const std::vector<char>& ground,
                                            const CardBandOptions& options) {
  std::vector<Eigen::Vector3d> upright_points;
  for (std::size_t i = 0; i < points_lidar.size(); ++i) {
    if (!ground[i] && std::isfinite(intensities[i])) upright_points.push_back(points_lidar[i]);
  }
  const double tol = options.card_plane_tolerance_m;
  std::optional<Plane> first =
      upright_points.size() >= 20
          ? ransac_plane(upright_points, 0.5 * tol, options.ransac_iterations, options.seed)
          : std::nullopt;
  std::optional<Plane> second;
  if (first) {
    std::vector<Eigen::Vector3d> off;
    for (const auto& p : upright_points) {
      if (std::abs(first->distance(p)) > tol) off.push_back(p);
    }
    if (off.size() >= 20) second = ransac_plane(off, 0.5 * tol, options.ransac_iterations, options.seed + 1);
  }
  if (!first || !second) {
    std::ostringstream os;
    os << "found " << (first ? 1 : 0) + (second ? 1 : 0) << " upright plane(s) among " << upright_points.size()
       << " coloured points off the ground: expected a card before a cloth in view of the camera";
    throw core::Error("measure_card_band", os.str());
  }
  for (Plane* p : {&*first, &*second}) {
    if (p->normal.dot(p->point) > 0.0) p->normal = -p->normal;  // towards the LIDAR
  }
  const bool first_is_card = std::abs(first->normal.dot(first->point)) < std::abs(second->normal.dot(second->point));
  return first_is_card ? std::make_pair(*first, *second) : std::make_pair(*second, *first);
}

CardGeometry card_geometry(const std::vector<Eigen::Vector3d>& points_lidar,
                           const std::vector<double>& intensities, const std::vector<char>& ground,
                           const CardBandOptions& options) {
  CardGeometry g;
  std::tie(g.card, g.cloth) = find_card_and_cloth(points_lidar, intensities, ground, options);
  const Plane& plane = g.card;
  const Plane& cloth = g.cloth;
  core::log_debug("measure_card_band: card plane at ", std::abs(plane.normal.dot(plane.point)), " m, cloth plane at ",
                  std::abs(cloth.normal.dot(cloth.point)), " m");

  // Card axes: x right and y up as seen from the LIDAR.
  g.x_axis = Eigen::Vector3d::UnitZ().cross(plane.normal);
  g.x_axis.normalize();
  g.y_axis = plane.normal.cross(g.x_axis);

  // Every point on the card plane along its LIDAR ray, in card coordinates; geometric class:
  // on the card, on the cloth, or between them (LIDAR mixed pixels at the card's edges: a
  // beam straddling the edge returns a range in between; they are neither and are ignored).
  const std::size_t n = points_lidar.size();
  const double tol = options.card_plane_tolerance_m;
  g.xy.assign(n, Eigen::Vector2d::Zero());
  g.geometry.assign(n, 0);
  g.between.assign(n, 0);
  const double plane_offset = plane.normal.dot(plane.point);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = points_lidar[i];
    if (ground[i]) continue;
    const double n_dot_p = plane.normal.dot(p);
    if (std::abs(n_dot_p) < 1e-9 || !std::isfinite(n_dot_p)) continue;
    const double s = plane_offset / n_dot_p;
    if (!(s > 0.0)) continue;
    const Eigen::Vector3d q = s * p - plane.point;
    g.xy[i] = Eigen::Vector2d(q.dot(g.x_axis), q.dot(g.y_axis));
    const double d = plane.distance(p);
    if (std::abs(d) <= tol) {
      g.geometry[i] = 1;
    } else if (std::abs(cloth.distance(p)) <= tol) {
      g.geometry[i] = -1;
    } else {
      g.between[i] = d < 0.0 && cloth.distance(p) > 0.0;
    }
  }
  return g;
}

/// The region around the card [card coordinates, m].
struct CardRoi {
  double x0, x1, y0, y1;
  bool contains(const Eigen::Vector2d& v) const {
    return v.x() >= x0 && v.x() <= x1 && v.y() >= y0 && v.y() <= y1;
  }
};

/// Card extent: robust extent of the card points, widened by the strip.
CardRoi card_roi(const CardGeometry& g, const std::vector<double>& intensities,
                 const CardBandOptions& options) {
  std::vector<double> bx, by;
  for (std::size_t i = 0; i < g.xy.size(); ++i) {
    if (g.geometry[i] == 1 && std::isfinite(intensities[i])) {
      bx.push_back(g.xy[i].x());
      by.push_back(g.xy[i].y());
    }
  }
  if (bx.size() < 20) throw core::Error("measure_card_band", "fewer than 20 coloured points lie on the card plane");
  const double roi_x0 = quantile(bx, 0.005) - options.edge_strip_m, roi_x1 = quantile(bx, 0.995) + options.edge_strip_m;
  const double roi_y0 = quantile(by, 0.005) - options.edge_strip_m, roi_y1 = quantile(by, 0.995) + options.edge_strip_m;
  return CardRoi{roi_x0, roi_x1, roi_y0, roi_y1};
}

/// Colour classes from the two surfaces' own colours near the card: the threshold is halfway
/// between the median card colour and the median cloth colour (bands are a minority of both).
void set_colour_threshold(const CardGeometry& g, const std::vector<double>& intensities,
                          const CardRoi& roi, CardBandMeasurement* m) {
  std::vector<double> card_colours, cloth_colours;
  for (std::size_t i = 0; i < g.xy.size(); ++i) {
    if (!std::isfinite(intensities[i]) || !roi.contains(g.xy[i])) continue;
    if (g.geometry[i] == 1) card_colours.push_back(intensities[i]);
    if (g.geometry[i] == -1) cloth_colours.push_back(intensities[i]);
  }
  if (cloth_colours.size() < 10) {
    throw core::Error("measure_card_band", "fewer than 10 cloth points around the card: expected a background around it");
  }
  const double card_median = quantile(card_colours, 0.5), cloth_median = quantile(cloth_colours, 0.5);
  if (card_median == cloth_median) {
    std::ostringstream os;
    os << "card and cloth have the same median colour (" << card_median << "): no contrast to measure a band";
    throw core::Error("measure_card_band", os.str());
  }
  m->card_is_bright = card_median > cloth_median;
  m->intensity_threshold = 0.5 * (card_median + cloth_median);
  core::log_debug("measure_card_band: card colour ", card_median, ", cloth colour ", cloth_median,
                  ", threshold ", m->intensity_threshold);
}

bool looks_like_card(const CardBandMeasurement& m, double intensity) {
  return (intensity > m.intensity_threshold) == m.card_is_bright;
}

/// The card points' extent within the region [card coordinates, m] and its centre.
struct CardExtent {
  double x0, x1, y0, y1;
  Eigen::Vector2d centre;
};

CardExtent card_extent(const CardGeometry& g, const CardRoi& roi) {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (std::size_t i = 0; i < g.xy.size(); ++i) {
    if (g.geometry[i] != 1 || !roi.contains(g.xy[i])) continue;
    x0 = std::min(x0, g.xy[i].x());
    x1 = std::max(x1, g.xy[i].x());
    y0 = std::min(y0, g.xy[i].y());
    y1 = std::max(y1, g.xy[i].y());
  }
  return CardExtent{x0, x1, y0, y1, Eigen::Vector2d(0.5 * (x0 + x1), 0.5 * (y0 + y1))};
}

/// The card's size, centre, normal, axes and range in *m; throws when the corner margins
/// leave no edge to measure.
void set_card_frame(const CardGeometry& g, const CardExtent& e, const CardBandOptions& options,
                    CardBandMeasurement* m) {
  m->card_size_m = Eigen::Vector2d(e.x1 - e.x0, e.y1 - e.y0);
  m->card_centre_lidar = g.card.point + e.centre.x() * g.x_axis + e.centre.y() * g.y_axis;
  m->card_normal_lidar = g.card.normal;
  m->card_x_lidar = g.x_axis;
  m->card_y_lidar = g.y_axis;
  m->card_range_m = m->card_centre_lidar.norm();

  if (!(m->card_size_m.x() > 2.0 * options.corner_margin_m &&
        m->card_size_m.y() > 2.0 * options.corner_margin_m)) {
    std::ostringstream os;
    os << "card of " << m->card_size_m.x() << " x " << m->card_size_m.y()
       << " m leaves no edge to measure once "
       << "corner_margin_m = " << options.corner_margin_m << " is cut off both ends";
    throw core::Error("measure_card_band", os.str());
  }
}

/// The card and background point counts and the card's point density in *m.
void measure_density(const CardGeometry& g, const std::vector<double>& intensities,
                     const CardRoi& roi, CardBandMeasurement* m) {
  const std::size_t n = g.xy.size();
  // Point density from the local sampling lattice rather than from a count in a window:
  // a count is quantised by whole scan lines / beams (+-15 % at 15 m), the lattice is not.
  // For each card point, a = nearest card point roughly along x (either side), b = roughly
  // along y; |a x b| is the area of its lattice cell; the median over points is robust to
  // noise and to the card's border (a border point still has neighbours on one side).
  std::vector<Eigen::Vector2d> card_xy;
  for (std::size_t i = 0; i < n; ++i) {
    if (g.geometry[i] != 1 || !roi.contains(g.xy[i])) continue;
    card_xy.push_back(g.xy[i]);
    if (std::isfinite(intensities[i])) ++m->card_points;
  }
  for (std::size_t i = 0; i < n; ++i) {
    m->background_points +=
        g.geometry[i] == -1 && std::isfinite(intensities[i]) && roi.contains(g.xy[i]);
  }
  const double kCone = std::tan(30.0 * M_PI / 180.0);  // "roughly along an axis"
  std::vector<double> cell_areas;
  for (const auto& p : card_xy) {
    Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
    double best_a = std::numeric_limits<double>::infinity(), best_b = best_a;
    for (const auto& q : card_xy) {
      const Eigen::Vector2d d = q - p;
      const double len = d.norm();
      if (len < 1e-9) continue;
      if (std::abs(d.y()) <= kCone * std::abs(d.x()) && len < best_a) {
        best_a = len;
        a = d;
      } else if (std::abs(d.x()) <= kCone * std::abs(d.y()) && len < best_b) {
        best_b = len;
        b = d;
      }
    }
    const double area = std::abs(a.x() * b.y() - a.y() * b.x());
    if (area > 0.0) cell_areas.push_back(area);
  }
  if (cell_areas.size() < 5) throw core::Error("measure_card_band", "cannot find the sampling lattice of the card points");
  m->density_per_m2 = 1.0 / quantile(cell_areas, 0.5);
}

/// The mis-coloured band of each edge of the card in m->edges.
void measure_edge_bands(const CardGeometry& g, const std::vector<double>& intensities,
                        const CardExtent& extent, const CardBandOptions& options,
                        CardBandMeasurement* m) {
  const double x0 = extent.x0, x1 = extent.x1, y0 = extent.y0, y1 = extent.y1;
  // Bands. Edge e runs along `along` (0 = x, 1 = y) at position `at` of the other coordinate.
  struct EdgeSpec {
    const char* name;
    int across;  // coordinate index across the edge
    double at;
    double outward;  // +1 when "beyond the card" is the positive direction
  };
  const EdgeSpec specs[4] = {{"left", 0, x0, -1.0}, {"right", 0, x1, 1.0}, {"bottom", 1, y0, -1.0}, {"top", 1, y1, 1.0}};
  for (int e = 0; e < 4; ++e) {
    const EdgeSpec& spec = specs[e];
    const int along = 1 - spec.across;
    const double lo = (along == 0 ? x0 : y0) + options.corner_margin_m;
    const double hi = (along == 0 ? x1 : y1) - options.corner_margin_m;
    EdgeBand& band = m->edges[e];
    band.name = spec.name;
    band.length_m = hi - lo;
    int inward = 0, outward = 0;
    for (std::size_t i = 0; i < g.xy.size(); ++i) {
      if (g.geometry[i] == 0 || !std::isfinite(intensities[i])) continue;
      const double a = g.xy[i][along], c = g.xy[i][spec.across];
      if (a < lo || a > hi || std::abs(c - spec.at) > options.edge_strip_m) continue;
      ++band.strip_points;
      const bool card_coloured = looks_like_card(*m, intensities[i]);
      if (g.geometry[i] == 1 && !card_coloured) ++inward;
      if (g.geometry[i] == -1 && card_coloured) ++outward;
    }
    band.miscoloured_points = inward + outward;
    const double per_metre = m->density_per_m2 * band.length_m;
    band.inward_m = inward / per_metre;
    band.outward_m = outward / per_metre;
    band.width_m = band.inward_m + band.outward_m;
  }
}

/// The coloured points around the card with their classes in m->points (centred on the
/// card), leaving out those in front of it.
void keep_card_points(const std::vector<Eigen::Vector3d>& points_lidar,
                      const std::vector<double>& intensities, const CardGeometry& g,
                      const CardRoi& roi, const CardExtent& extent, const CardBandOptions& options,
                      CardBandMeasurement* m) {
  for (std::size_t i = 0; i < points_lidar.size(); ++i) {
    if (!std::isfinite(intensities[i]) || !roi.contains(g.xy[i])) continue;
    const bool card_coloured = looks_like_card(*m, intensities[i]);
    CardPoint p{g.xy[i] - extent.centre, intensities[i], CardPointClass::kMixed};
    if (g.geometry[i] == 1)
      p.label = card_coloured ? CardPointClass::kCard : CardPointClass::kCardMiscoloured;
    if (g.geometry[i] == -1) {
      p.label =
          card_coloured ? CardPointClass::kBackgroundMiscoloured : CardPointClass::kBackground;
    }
    if (g.geometry[i] == 0 && g.card.distance(points_lidar[i]) > options.card_plane_tolerance_m)
      continue;  // in front
    m->points.push_back(p);
  }
}

}  // namespace

std::vector<double> sample_point_intensities(const std::vector<Eigen::Vector3d>& points_lidar,
                                             const core::PinholeCamera& camera,
                                             const Eigen::Isometry3d& T_camera_lidar,
                                             const GrayImage& image) {
  if (image.width != camera.width() || image.height != camera.height()) {
    std::ostringstream os;
    os << "image is " << image.width << "x" << image.height << " but camera '"
       << camera.intrinsics().camera_name << "' is " << camera.width() << "x" << camera.height();
    throw std::invalid_argument(os.str());
  }
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw std::invalid_argument("image.pixels does not hold width * height values");
  }
  std::vector<double> out(points_lidar.size(), kNaN);
  for (std::size_t i = 0; i < points_lidar.size(); ++i) {
    Eigen::Vector2d uv;
    if (!camera.project(T_camera_lidar * points_lidar[i], &uv)) continue;
    const long u = std::lround(uv.x()), v = std::lround(uv.y());  // pixel centres are integers
    if (u < 0 || v < 0 || u >= image.width || v >= image.height) continue;
    out[i] = image.at(static_cast<int>(u), static_cast<int>(v));
  }
  return out;
}

std::string CardBandOptions::validate() const {
  std::ostringstream os;
  if (!(card_plane_tolerance_m > 0.0)) {
    os << "card_plane_tolerance_m = " << card_plane_tolerance_m << ": expected > 0";
  } else if (!(edge_strip_m > 0.0)) {
    os << "edge_strip_m = " << edge_strip_m << ": expected > 0";
  } else if (!(corner_margin_m >= 0.0)) {
    os << "corner_margin_m = " << corner_margin_m << ": expected >= 0";
  } else if (ransac_iterations < 1) {
    os << "ransac_iterations = " << ransac_iterations << ": expected >= 1";
  }
  return os.str();
}

CardBandMeasurement measure_card_band(const std::vector<Eigen::Vector3d>& points_lidar,
                                      const std::vector<double>& intensities,
                                      const CardBandOptions& options) {
  if (auto why = options.validate(); !why.empty())
    throw std::invalid_argument("CardBandOptions: " + why);
  if (points_lidar.size() != intensities.size()) {
    std::ostringstream os;
    os << "measure_card_band: " << points_lidar.size() << " points but " << intensities.size()
       << " intensities";
    throw std::invalid_argument(os.str());
  }
  CardBandMeasurement m;
  const std::vector<char> ground = find_ground(points_lidar, intensities, options, &m);
  const CardGeometry g = card_geometry(points_lidar, intensities, ground, options);
  const CardRoi roi = card_roi(g, intensities, options);
  for (std::size_t i = 0; i < points_lidar.size(); ++i)
    m.mixed_points += g.between[i] && roi.contains(g.xy[i]);
  set_colour_threshold(g, intensities, roi, &m);
  const CardExtent extent = card_extent(g, roi);
  set_card_frame(g, extent, options, &m);
  measure_density(g, intensities, roi, &m);
  measure_edge_bands(g, intensities, extent, options, &m);
  m.x0_m = extent.x0 - extent.centre.x();
  m.x1_m = extent.x1 - extent.centre.x();
  m.y0_m = extent.y0 - extent.centre.y();
  m.y1_m = extent.y1 - extent.centre.y();
  if (options.keep_points) keep_card_points(points_lidar, intensities, g, roi, extent, options, &m);
  m.band_x_m = 0.5 * (m.edges[0].width_m + m.edges[1].width_m);
  m.band_y_m = 0.5 * (m.edges[2].width_m + m.edges[3].width_m);
  core::log_debug("measure_card_band: card ", m.card_size_m.transpose(), " m at ", m.card_range_m, " m, ",
                  m.card_points, " card points, band x ", m.band_x_m, " m, y ", m.band_y_m, " m");
  return m;
}

Eigen::Vector3d colour_source_offset(const Eigen::Vector3d& point_lidar, const Eigen::Vector3d& plane_normal_lidar,
                                     const core::PinholeCamera& camera_true,
                                     const Eigen::Isometry3d& T_camera_lidar_true,
                                     const core::PinholeCamera& camera_estimated,
                                     const Eigen::Isometry3d& T_camera_lidar_estimated) {
  Eigen::Vector2d uv;
  if (!camera_estimated.project(T_camera_lidar_estimated * point_lidar, &uv)) {
    throw std::invalid_argument("colour_source_offset: point is behind the (estimated) camera");
  }
  if (!((T_camera_lidar_true * point_lidar).z() > 0.0)) {
    throw std::invalid_argument("colour_source_offset: point is behind the (true) camera");
  }
  const Eigen::Isometry3d T_lidar_camera = T_camera_lidar_true.inverse();
  const Eigen::Vector3d origin = T_lidar_camera.translation();
  const Eigen::Vector3d direction = T_lidar_camera.linear() * camera_true.unproject(uv);
  const Eigen::Vector3d nrm = plane_normal_lidar.normalized();
  const double denom = nrm.dot(direction);
  if (std::abs(denom) < 1e-12) throw std::invalid_argument("colour_source_offset: plane seen edge-on");
  const Eigen::Vector3d shown = origin + (nrm.dot(point_lidar - origin) / denom) * direction;
  return shown - point_lidar;
}

}  // namespace rgbdt::error_model
