#include "rgbdt/calib_targets/lidar_target.hpp"

#include <ceres/ceres.h>
#include <pcl/ModelCoefficients.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/segmentation/region_growing.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/log.hpp"

namespace rgbdt::calib_targets {

namespace {

constexpr double kPi = 3.14159265358979323846;

using Vec3 = Eigen::Vector3d;
using Vec2 = Eigen::Vector2d;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const std::vector<Vec3>& pts,
                                           const std::vector<int>& idx) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr out(new pcl::PointCloud<pcl::PointXYZ>);
  out->reserve(idx.size());
  for (int i : idx) {
    const Vec3& p = pts[static_cast<std::size_t>(i)];
    out->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                 static_cast<float>(p.z())));
  }
  return out;
}

/// SAC plane segmentation (PCL) of pts[idx]; inliers as indices into pts.
bool sac_plane(const std::vector<Vec3>& pts, const std::vector<int>& idx, double threshold,
               std::vector<int>* inliers, std::vector<int>* outliers, int iterations = 500) {
  if (idx.size() < 3) return false;
  auto pc = to_pcl(pts, idx);
  pcl::SACSegmentation<pcl::PointXYZ> seg;
  seg.setOptimizeCoefficients(true);
  seg.setModelType(pcl::SACMODEL_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setDistanceThreshold(threshold);
  seg.setMaxIterations(iterations);
  pcl::PointIndices in;
  pcl::ModelCoefficients coeff;
  seg.setInputCloud(pc);
  seg.segment(in, coeff);
  if (in.indices.size() < 3) return false;
  std::vector<char> is_in(idx.size(), 0);
  for (int k : in.indices) is_in[static_cast<std::size_t>(k)] = 1;
  inliers->clear();
  if (outliers) outliers->clear();
  for (std::size_t k = 0; k < idx.size(); ++k) {
    if (is_in[k]) {
      inliers->push_back(idx[k]);
    } else if (outliers) {
      outliers->push_back(idx[k]);
    }
  }
  return true;
}

/// Euclidean clusters of pts[idx] (PCL), largest first, as indices into pts.
std::vector<std::vector<int>> clusters_of(const std::vector<Vec3>& pts, const std::vector<int>& idx,
                                          double tolerance, int min_size) {
  auto pc = to_pcl(pts, idx);
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  tree->setInputCloud(pc);
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
  ec.setClusterTolerance(tolerance);
  ec.setMinClusterSize(min_size);
  ec.setMaxClusterSize(static_cast<int>(idx.size()) + 1);
  ec.setSearchMethod(tree);
  ec.setInputCloud(pc);
  std::vector<pcl::PointIndices> found;
  ec.extract(found);
  std::vector<std::vector<int>> out;
  for (const auto& c : found) {
    std::vector<int> v;
    v.reserve(c.indices.size());
    for (int k : c.indices) v.push_back(idx[static_cast<std::size_t>(k)]);
    out.push_back(std::move(v));
  }
  return out;
}

/// Least-squares plane through pts[idx] with normal towards the sensor (origin).
Eigen::Vector4d fit_plane(const std::vector<Vec3>& pts, const std::vector<int>& idx) {
  Vec3 mean = Vec3::Zero();
  for (int i : idx) mean += pts[static_cast<std::size_t>(i)];
  mean /= static_cast<double>(idx.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int i : idx) {
    const Vec3 d = pts[static_cast<std::size_t>(i)] - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Vec3 n = es.eigenvectors().col(0).normalized();
  if (n.dot(mean) > 0) n = -n;  // towards the sensor at the origin
  return Eigen::Vector4d(n.x(), n.y(), n.z(), -n.dot(mean));
}

/// In-plane frame of a board: y = up projected into the plane, x = y cross n (board frame
/// of contracts.md: x right as seen from the sensor, y up, z = n towards the sensor).
struct PlaneFrame {
  Vec3 origin, ex, ey, n;
  Vec2 to2d(const Vec3& p) const { return Vec2((p - origin).dot(ex), (p - origin).dot(ey)); }
  Vec3 to3d(const Vec2& q) const { return origin + q.x() * ex + q.y() * ey; }
};

PlaneFrame make_frame(const Eigen::Vector4d& plane, const Vec3& centroid, const Vec3& up) {
  PlaneFrame f;
  f.n = plane.head<3>().normalized();
  f.origin = centroid - (f.n.dot(centroid) + plane[3]) * f.n;
  Vec3 ey = up - up.dot(f.n) * f.n;
  if (ey.norm() < 1e-3) {  // board parallel to the floor: any in-plane direction
    ey = f.n.unitOrthogonal();
  }
  f.ey = ey.normalized();
  f.ex = f.ey.cross(f.n).normalized();
  return f;
}

/// Scan lines of the board points: ring ids, or recovered by clustering elevations.
std::vector<int> recover_lines(const std::vector<Vec3>& pts, const std::vector<int>& idx,
                               const Vec3& up, double gap_rad) {
  std::vector<std::pair<double, int>> elev;
  elev.reserve(idx.size());
  for (std::size_t k = 0; k < idx.size(); ++k) {
    const Vec3 d = pts[static_cast<std::size_t>(idx[k])].normalized();
    elev.emplace_back(std::asin(std::clamp(d.dot(up), -1.0, 1.0)), static_cast<int>(k));
  }
  std::sort(elev.begin(), elev.end());
  if (gap_rad <= 0.0) {
    // Elevations of one beam agree to float precision; distinct beams differ by >= ~0.1 deg.
    std::vector<double> gaps;
    for (std::size_t k = 1; k < elev.size(); ++k) {
      const double g = elev[k].first - elev[k - 1].first;
      if (g > 2e-4) gaps.push_back(g);
    }
    gap_rad = gaps.empty() ? 1e-3 : 0.5 * median(gaps);
  }
  std::vector<int> line(idx.size(), 0);
  int id = 0;
  for (std::size_t k = 0; k < elev.size(); ++k) {
    if (k > 0 && elev[k].first - elev[k - 1].first > gap_rad) ++id;
    line[static_cast<std::size_t>(elev[k].second)] = id;
  }
  return line;
}

struct HoleCandidate {
  Vec2 center;       ///< board-plane coordinates [m]
  double empty_r;    ///< radius of the largest empty disc there [m]
};

/// Empty discs in the board's in-plane occupancy (the detector that needs no scan lines).
std::vector<HoleCandidate> find_empty_discs(const std::vector<Vec2>& q, double radius,
                                            double cell) {
  std::vector<HoleCandidate> out;
  if (q.size() < 10) return out;
  Vec2 lo = q[0], hi = q[0];
  for (const Vec2& p : q) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = 2.0 * cell;
  lo -= Vec2(margin, margin);
  hi += Vec2(margin, margin);
  const int w = static_cast<int>(std::ceil((hi.x() - lo.x()) / cell)) + 1;
  const int h = static_cast<int>(std::ceil((hi.y() - lo.y()) / cell)) + 1;
  if (w > 4000 || h > 4000 || w < 3 || h < 3) return out;
  cv::Mat empty(h, w, CV_8U, cv::Scalar(255));
  std::vector<cv::Point> cells;
  cells.reserve(q.size());
  for (const Vec2& p : q) {
    const int x = static_cast<int>((p.x() - lo.x()) / cell);
    const int y = static_cast<int>((p.y() - lo.y()) / cell);
    empty.at<uchar>(y, x) = 0;
    cells.emplace_back(x, y);
  }
  std::vector<cv::Point> hull;
  cv::convexHull(cells, hull);
  cv::Mat inside(h, w, CV_8U, cv::Scalar(0));
  cv::fillConvexPoly(inside, hull, cv::Scalar(255));
  cv::Mat dist;
  cv::distanceTransform(empty, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::Mat big = (dist >= static_cast<float>(0.6 * radius / cell)) & inside;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(big, labels, stats, centroids, 8);
  std::vector<float> best(static_cast<std::size_t>(n), -1.0f);
  std::vector<cv::Point> best_at(static_cast<std::size_t>(n));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int l = labels.at<int>(y, x);
      if (l <= 0) continue;
      const float d = dist.at<float>(y, x);
      if (d > best[static_cast<std::size_t>(l)]) {
        best[static_cast<std::size_t>(l)] = d;
        best_at[static_cast<std::size_t>(l)] = cv::Point(x, y);
      }
    }
  }
  for (int l = 1; l < n; ++l) {
    const double r = best[static_cast<std::size_t>(l)] * cell;
    if (r > 2.0 * radius) continue;  // a gap in the board, not a hole of this target
    const cv::Point c = best_at[static_cast<std::size_t>(l)];
    out.push_back({Vec2(lo.x() + (c.x + 0.5) * cell, lo.y() + (c.y + 0.5) * cell), r});
  }
  return out;
}

/// True when board points surround the disc (centre c, radius r) on (nearly) all sides.
bool enclosed(const std::vector<Vec2>& q, const Vec2& c, double r) {
  constexpr int kSectors = 12;
  std::array<bool, kSectors> hit{};
  for (const Vec2& p : q) {
    const Vec2 d = p - c;
    const double dn = d.norm();
    if (dn < 0.7 * r || dn > 2.0 * r) continue;
    const double a = std::atan2(d.y(), d.x()) + kPi;
    hit[static_cast<std::size_t>(std::min(kSectors - 1, static_cast<int>(a / (2 * kPi) * kSectors)))] = true;
  }
  return std::count(hit.begin(), hit.end(), true) >= kSectors - 2;
}

/// Matches layout holes (board frame) to candidates by a 2D rigid transform; returns the
/// initial centre (board-plane coordinates) of every layout hole, predicted when no
/// candidate matched it, or empty when fewer than min(2, N) holes matched.
std::vector<Vec2> match_layout(const std::vector<Vec2>& layout,
                               const std::vector<HoleCandidate>& cand, double radius,
                               int* matched_out) {
  const std::size_t n = layout.size();
  *matched_out = 0;
  if (cand.empty()) return {};
  if (n == 1) {
    // The candidate whose empty disc best matches the radius.
    std::size_t best = 0;
    for (std::size_t k = 1; k < cand.size(); ++k) {
      if (std::abs(cand[k].empty_r - radius) < std::abs(cand[best].empty_r - radius)) best = k;
    }
    *matched_out = 1;
    return {cand[best].center};
  }
  const double tol = 0.5 * radius;
  int best_matches = 0;
  double best_angle = 1e9, best_err = 1e9;
  std::vector<Vec2> best_pred;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = 0; b < n; ++b) {
      if (a == b) continue;
      const Vec2 dl = layout[b] - layout[a];
      for (std::size_t i = 0; i < cand.size(); ++i) {
        for (std::size_t j = 0; j < cand.size(); ++j) {
          if (i == j) continue;
          const Vec2 dc = cand[j].center - cand[i].center;
          if (std::abs(dc.norm() - dl.norm()) > tol) continue;
          const double angle = std::atan2(dc.y(), dc.x()) - std::atan2(dl.y(), dl.x());
          const Eigen::Rotation2Dd R(angle);
          const Vec2 t = cand[i].center - R * layout[a];
          int matches = 0;
          double err = 0.0;
          std::vector<Vec2> pred(n);
          for (std::size_t k = 0; k < n; ++k) {
            pred[k] = R * layout[k] + t;
            double dmin = 1e9;
            std::size_t kmin = 0;
            for (std::size_t m = 0; m < cand.size(); ++m) {
              const double d = (cand[m].center - pred[k]).norm();
              if (d < dmin) {
                dmin = d;
                kmin = m;
              }
            }
            if (dmin < tol) {
              ++matches;
              err += dmin;
              pred[k] = cand[kmin].center;
            }
          }
          const double wrapped = std::abs(std::remainder(angle, 2 * kPi));
          // Most matches; then the rotation closest to "board y up" (symmetric layouts);
          // then the smallest distance.
          const bool better =
              matches > best_matches ||
              (matches == best_matches && (wrapped < best_angle - 0.3 ||
                                           (std::abs(wrapped - best_angle) <= 0.3 && err < best_err)));
          if (better) {
            best_matches = matches;
            best_angle = wrapped;
            best_err = err;
            best_pred = pred;
          }
        }
      }
    }
  }
  *matched_out = best_matches;
  if (best_matches < 2) return {};
  return best_pred;
}

/// Per-line theta discontinuities (Algorithm 2, lines 7-22) on the board points.
/// Returns edge points (3D) with the half-step correction applied when asked.
std::vector<Vec3> scan_line_edges(const std::vector<Vec3>& pts, const std::vector<int>& idx,
                                  const std::vector<int>& line, const PlaneFrame& frame,
                                  const LidarDetectionOptions& options, std::vector<int>* edge_lines) {
  std::map<int, std::vector<int>> by_line;  // Algorithm 2, lines 7-13
  for (std::size_t k = 0; k < idx.size(); ++k) by_line[line[k]].push_back(idx[k]);
  std::vector<Vec3> edges;
  for (auto& [id, members] : by_line) {
    if (members.size() < 4) continue;
    // theta: angle of the beam within the line's fan (spherical coordinates of the paper).
    std::vector<Vec3> dirs;
    Vec3 mean = Vec3::Zero();
    for (int i : members) {
      dirs.push_back(pts[static_cast<std::size_t>(i)].normalized());
      mean += dirs.back();
    }
    mean.normalize();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const Vec3& d : dirs) cov += (d - mean) * (d - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    Vec3 along = es.eigenvectors().col(2);
    along = (along - along.dot(mean) * mean).normalized();
    std::vector<std::pair<double, int>> th;
    for (std::size_t k = 0; k < members.size(); ++k) {
      th.emplace_back(std::atan2(dirs[k].dot(along), dirs[k].dot(mean)), members[k]);
    }
    std::sort(th.begin(), th.end());  // SortByTheta
    std::vector<double> steps;
    for (std::size_t k = 1; k < th.size(); ++k) steps.push_back(th[k].first - th[k - 1].first);
    const double step = median(steps);
    const double gap = std::max(options.min_theta_gap_rad, options.theta_gap_factor * step);
    for (std::size_t k = 0; k + 1 < th.size(); ++k) {
      if (th[k + 1].first - th[k].first < gap) continue;  // Algorithm 2, line 17
      Vec3 a = pts[static_cast<std::size_t>(th[k].second)];
      Vec3 b = pts[static_cast<std::size_t>(th[k + 1].second)];
      if (options.half_step_correction) {
        // The true edge lies between the last board point and the next beam, which left
        // the board: on average half a step further (step at this range, in metres).
        const Vec3 u = (b - a).normalized();
        a += 0.5 * step * a.norm() * u;
        b -= 0.5 * step * b.norm() * u;
      }
      edges.push_back(frame.to3d(frame.to2d(a)));
      edges.push_back(frame.to3d(frame.to2d(b)));
      edge_lines->push_back(id);
      edge_lines->push_back(id);
    }
  }
  return edges;
}

/// Edges from the occupancy: in each angular bin around the hole, the board point nearest
/// to the centre (the inner border of the board).
std::vector<Vec3> occupancy_edges(const std::vector<Vec2>& q, const Vec2& c, double radius,
                                  double spacing, const PlaneFrame& frame,
                                  const LidarDetectionOptions& options) {
  const int bins = std::clamp(static_cast<int>(2 * kPi * radius / std::max(spacing, 1e-3)), 16, 180);
  std::vector<double> best(static_cast<std::size_t>(bins), 1e9);
  std::vector<Vec2> best_p(static_cast<std::size_t>(bins));
  for (const Vec2& p : q) {
    const Vec2 d = p - c;
    const double dn = d.norm();
    if (dn < 0.5 * radius || dn > 1.5 * radius) continue;
    const double a = std::atan2(d.y(), d.x()) + kPi;
    const auto b = static_cast<std::size_t>(std::min(bins - 1, static_cast<int>(a / (2 * kPi) * bins)));
    if (dn < best[b]) {
      best[b] = dn;
      best_p[b] = p;
    }
  }
  std::vector<Vec3> edges;
  for (int b = 0; b < bins; ++b) {
    if (best[static_cast<std::size_t>(b)] > 1.4 * radius) continue;
    Vec2 p = best_p[static_cast<std::size_t>(b)];
    if (options.half_step_correction) p -= 0.5 * spacing * (p - c).normalized();
    edges.push_back(frame.to3d(p));
  }
  return edges;
}

struct CircleResidual {
  CircleResidual(Vec3 p, Vec3 origin, Vec3 ex, Vec3 ey, double r)
      : p_(std::move(p)), o_(std::move(origin)), ex_(std::move(ex)), ey_(std::move(ey)), r_(r) {}
  template <typename T>
  bool operator()(const T* ab, T* residual) const {
    // c = origin + a ex + b ey: the centre stays in the board plane by construction.
    T d2 = T(0);
    for (int k = 0; k < 3; ++k) {
      const T c = T(o_[k]) + ab[0] * T(ex_[k]) + ab[1] * T(ey_[k]);
      const T d = T(p_[k]) - c;
      d2 += d * d;
    }
    // (|p - c|^2 - r^2) / (2 r): the fixed Eq. (1), scaled to metres near the circle.
    residual[0] = (d2 - T(r_ * r_)) / T(2.0 * r_);
    return true;
  }
  Vec3 p_, o_, ex_, ey_;
  double r_;
};

struct FreeCircleResidual {
  explicit FreeCircleResidual(Vec2 q) : q_(std::move(q)) {}
  template <typename T>
  bool operator()(const T* c, const T* r, T* residual) const {
    const T dx = T(q_.x()) - c[0];
    const T dy = T(q_.y()) - c[1];
    residual[0] = ceres::sqrt(dx * dx + dy * dy + T(1e-12)) - r[0];
    return true;
  }
  Vec2 q_;
};

/// Free-radius circle fit in the plane (for the reported radius).
double fit_free_radius(const std::vector<Vec3>& edges, const PlaneFrame& frame, Vec2 c,
                       double r) {
  double cr[2] = {c.x(), c.y()};
  double rr = r;
  ceres::Problem problem;
  for (const Vec3& e : edges) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<FreeCircleResidual, 1, 2, 1>(
                                 new FreeCircleResidual(frame.to2d(e))),
                             nullptr, cr, &rr);
  }
  ceres::Solver::Options so;
  so.max_num_iterations = 50;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  return rr;
}

struct BoardResult {
  bool ok = false;
  int matched = 0;     ///< layout holes matched by an empty disc
  double score = 0.0;  ///< lower is better: mean (|r_free - r| + rms) / r
  std::string reason;
  bool shadow = false;  ///< rejected by check_see_through (reason says which hole)
  Eigen::Vector4d plane;
  std::vector<LidarHole> holes;
  std::string method;
  std::string profile;
  double spacing_m = 0.0;
  double edge_bias_m = 0.0;
  std::string edge_bias_source = "none";
};

/// The board segment in its own plane frame, with its point spacing.
struct BoardGeometry {
  PlaneFrame frame;
  std::vector<Vec2> q;   ///< board points in plane coordinates [m]
  double spacing = 0.0;  ///< median nearest-neighbour distance in the plane [m]
};

BoardGeometry board_geometry(const std::vector<Vec3>& pts, const std::vector<int>& board,
                             const Eigen::Vector4d& plane, const Vec3& up) {
  BoardGeometry g;
  Vec3 centroid = Vec3::Zero();
  for (int i : board) centroid += pts[static_cast<std::size_t>(i)];
  centroid /= static_cast<double>(board.size());
  g.frame = make_frame(plane, centroid, up);
  g.q.reserve(board.size());
  for (int i : board) g.q.push_back(g.frame.to2d(pts[static_cast<std::size_t>(i)]));
  pcl::PointCloud<pcl::PointXYZ>::Ptr pc(new pcl::PointCloud<pcl::PointXYZ>);
  for (const Vec2& p : g.q) pc->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), 0.f));
  pcl::KdTreeFLANN<pcl::PointXYZ> kd;
  kd.setInputCloud(pc);
  std::vector<double> nn;
  std::vector<int> ki(2);
  std::vector<float> kd2(2);
  for (std::size_t k = 0; k < pc->size(); k += std::max<std::size_t>(1, pc->size() / 2000)) {
    if (kd.nearestKSearch(pc->points[k], 2, ki, kd2) == 2) nn.push_back(std::sqrt(kd2[1]));
  }
  g.spacing = median(nn);
  return g;
}

/// Board size sanity: the layout must fit in the segment's extent. Empty when it does.
std::string check_board_extent(const std::vector<Vec2>& q, const std::vector<Vec2>& layout,
                               const core::TargetSpec& target) {
  Vec2 lo = q[0], hi = q[0];
  for (const Vec2& p : q) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  Vec2 llo = layout[0], lhi = layout[0];
  for (const Vec2& p : layout) {
    llo = llo.cwiseMin(p);
    lhi = lhi.cwiseMax(p);
  }
  const double layout_extent = (lhi - llo).norm() + 2.0 * target.radius_m;
  const double extent = (hi - lo).norm();
  double max_extent = 4.0 * layout_extent + 1.0;
  if (target.board_size_m) max_extent = 1.5 * target.board_size_m->norm() + 0.3;
  if (extent >= layout_extent && extent <= max_extent) return {};
  std::ostringstream s;
  s << "plane segment of extent " << extent << " m does not fit the target (expected " << layout_extent << ".."
    << max_extent << " m)";
  return s.str();
}

/// Where the edges come from, measured on the board: its scan lines (ring field, or lines
/// recovered from the elevations when most board points lie on lines of >= 5 points), or
/// none (a dense cloud without lines: occupancy edges).
struct EdgeSource {
  bool use_lines = false;
  std::vector<int> lines;  ///< line id per board point
  std::string method = "occupancy";
  std::string reason;      ///< non-empty: the requested method is impossible
};

EdgeSource choose_edge_source(const std::vector<Vec3>& pts, const std::vector<int>& board,
                              const std::vector<int>& rings, bool has_ring,
                              const LidarDetectionOptions& options) {
  EdgeSource src;
  if (options.edge_method == LidarEdgeMethod::kOccupancy) return src;
  if (has_ring) {
    for (int i : board) src.lines.push_back(rings[static_cast<std::size_t>(i)]);
    src.use_lines = true;
    src.method = "scan_lines (ring)";
    return src;
  }
  src.lines = recover_lines(pts, board, options.up_lidar, options.scan_line_gap_rad);
  std::map<int, int> count;
  for (int l : src.lines) ++count[l];
  std::size_t in_long = 0;
  for (const auto& [l, c] : count) {
    if (c >= 5) in_long += static_cast<std::size_t>(c);
  }
  // Lines of a multi-beam LIDAR are tight in elevation (one beam: equal to float precision)
  // and far apart (width < half the gap); elevation clusters of a non-repetitive pattern
  // are as wide as their gaps.
  std::map<int, std::pair<double, double>> lo_hi;
  for (std::size_t k = 0; k < board.size(); ++k) {
    const double e = std::asin(std::clamp(pts[static_cast<std::size_t>(board[k])].normalized().dot(options.up_lidar), -1.0, 1.0));
    auto it = lo_hi.find(src.lines[k]);
    if (it == lo_hi.end()) lo_hi[src.lines[k]] = {e, e};
    else it->second = {std::min(it->second.first, e), std::max(it->second.second, e)};
  }
  std::vector<double> widths, gaps;
  double prev_hi = 0.0;
  bool first = true;
  for (const auto& [l, range] : lo_hi) {
    widths.push_back(range.second - range.first);
    if (!first) gaps.push_back(range.first - prev_hi);
    prev_hi = range.second;
    first = false;
  }
  const bool tight = !gaps.empty() && median(widths) < 0.5 * median(gaps);
  if (tight && count.size() >= 3 && in_long >= 0.8 * static_cast<double>(board.size())) {
    src.use_lines = true;
    src.method = "scan_lines (recovered)";
  } else if (options.edge_method == LidarEdgeMethod::kScanLines) {
    src.reason = "no ring field and no scan lines recoverable from the elevations";
  } else {
    src.lines.clear();
  }
  return src;
}

/// Edge points of the hole near c2 (two passes: gather near the circle, fit the centre with
/// the known radius, gather again closer), then outlier rejection. Empty on failure.
std::vector<Vec3> hole_edges(const std::vector<Vec3>& line_edges, const std::vector<int>& line_ids,
                             const BoardGeometry& g, double r, const LidarDetectionOptions& options,
                             bool use_lines, Vec2* c2, std::vector<int>* edge_lines, bool* fell_back) {
  std::vector<Vec3> edges;
  for (int pass = 0; pass < 2; ++pass) {
    edges.clear();
    edge_lines->clear();
    if (use_lines) {
      for (std::size_t k = 0; k < line_edges.size(); ++k) {
        if (std::abs((g.frame.to2d(line_edges[k]) - *c2).norm() - r) < (pass == 0 ? 0.5 : 0.25) * r) {
          edges.push_back(line_edges[k]);
          edge_lines->push_back(line_ids[k]);
        }
      }
    }
    if (static_cast<int>(edges.size()) < options.min_edge_points &&
        options.edge_method != LidarEdgeMethod::kScanLines) {
      edges = occupancy_edges(g.q, *c2, r, g.spacing, g.frame, options);
      edge_lines->clear();
      if (use_lines) *fell_back = true;
    }
    if (static_cast<int>(edges.size()) < options.min_edge_points) return {};
    const Vec3 c3 = fit_circle_center_in_plane(edges, g.frame.n, g.frame.origin, r, g.frame.to3d(*c2));
    *c2 = g.frame.to2d(c3);
  }
  // Outlier rejection (mixed returns at the rim, the board's outer border).
  std::vector<double> dev;
  for (const Vec3& e : edges) dev.push_back(std::abs((g.frame.to2d(e) - *c2).norm() - r));
  const double limit = std::max(0.02, 3.0 * 1.4826 * median(dev));
  std::vector<Vec3> kept;
  std::vector<int> kept_lines;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (dev[k] > limit) continue;
    kept.push_back(edges[k]);
    if (!edge_lines->empty()) kept_lines.push_back((*edge_lines)[k]);
  }
  if (static_cast<int>(kept.size()) < options.min_edge_points) return edges;
  *edge_lines = std::move(kept_lines);
  return kept;
}

/// Known-radius centre fit of one hole's edges, the free radius when the edges surround the
/// hole (>= 5 of 12 sectors; edges of one or two lines leave it unconstrained).
LidarHole fit_hole(std::vector<Vec3> edges, const std::vector<int>& edge_lines, const BoardGeometry& g,
                   const Vec2& c2, double r) {
  LidarHole hole;
  hole.center = fit_circle_center_in_plane(edges, g.frame.n, g.frame.origin, r, g.frame.to3d(c2), &hole.rms_m);
  hole.normal = g.frame.n;
  std::array<bool, 12> sector{};
  for (const Vec3& e : edges) {
    const Vec2 d = g.frame.to2d(e) - g.frame.to2d(hole.center);
    sector[static_cast<std::size_t>(std::min(11, static_cast<int>((std::atan2(d.y(), d.x()) + kPi) / (2 * kPi) * 12)))] = true;
  }
  hole.radius_measured = std::count(sector.begin(), sector.end(), true) >= 5;
  hole.radius_m = hole.radius_measured ? fit_free_radius(edges, g.frame, g.frame.to2d(hole.center), r) : r;
  hole.lines_across = static_cast<int>(std::set<int>(edge_lines.begin(), edge_lines.end()).size());
  hole.edge_points = std::move(edges);
  return hole;
}

/// The view's edge bias (mean free radius - r over measured holes, else the beam model) and
/// the centres refitted with radius r + bias.
void correct_edge_bias(const BoardGeometry& g, double r, const LidarDetectionOptions& options, BoardResult* res) {
  double sum = 0.0;
  int n = 0;
  for (const LidarHole& h : res->holes) {
    if (!h.radius_measured) continue;
    sum += h.radius_m - r;
    ++n;
  }
  double bias = 0.0;
  if (n > 0) {
    bias = sum / n;
    res->edge_bias_source = "measured on " + std::to_string(n) + " hole(s)";
  } else if (options.beam_divergence_rad > 0.0) {
    bias = 0.25 * options.beam_divergence_rad * res->holes[0].center.norm();
    res->edge_bias_source = "beam divergence model";
  }
  // A bias beyond the radius check's tolerance would have rejected the holes already.
  bias = std::clamp(bias, -options.max_radius_error * r, options.max_radius_error * r);
  res->edge_bias_m = bias;
  if (bias == 0.0) return;
  for (LidarHole& h : res->holes) {
    h.center = fit_circle_center_in_plane(h.edge_points, g.frame.n, g.frame.origin, r + bias, h.center, &h.rms_m);
    h.edge_bias_m = bias;
  }
}

/// Occupancy edges carry no scan-line structure to vouch for them: the board must surround
/// the fitted hole (>= 32 of 36 sectors of the ring 1.1-1.5 r hold points) and the hole must
/// be empty (inside 0.8 r fewer than 2 % of the ring's points). Empty when it does.
std::string check_hole_surroundings(const BoardGeometry& g, const LidarHole& hole, double r) {
  constexpr int kSectors = 36;
  std::array<bool, kSectors> hit{};
  const Vec2 c = g.frame.to2d(hole.center);
  int ring = 0, inside = 0;
  for (const Vec2& p : g.q) {
    const Vec2 d = p - c;
    const double dn = d.norm();
    if (dn < 0.8 * r) ++inside;
    if (dn < 1.1 * r || dn > 1.5 * r) continue;
    ++ring;
    const double a = std::atan2(d.y(), d.x()) + kPi;
    hit[static_cast<std::size_t>(std::min(kSectors - 1, static_cast<int>(a / (2 * kPi) * kSectors)))] = true;
  }
  const auto sectors = std::count(hit.begin(), hit.end(), true);
  std::ostringstream s;
  if (sectors < kSectors - 4) {
    s << "the board surrounds the hole at " << hole.center.transpose() << " in " << sectors << " of " << kSectors
      << " sectors (expected >= " << kSectors - 4 << ")";
  } else if (inside > 0.02 * ring) {
    s << "the hole at " << hole.center.transpose() << " holds " << inside << " points (expected empty)";
  }
  return s.str();
}

/// A hole lets the beams through: what a ray through it (within 0.8 r of the centre) hits
/// lies behind the board, or nothing does. A gap in a plane that something in front of it
/// casts (the board's shadow on the floor or a wall) is hit in front of the plane instead.
/// Empty when the rays through the hole mostly end behind it.
std::string check_see_through(const std::vector<Vec3>& pts, const LidarHole& hole, double r) {
  const Vec3& n = hole.normal;
  const double d = -n.dot(hole.center);
  // Beyond range noise and mixed pixels at the rim: 10 cm or a third of the radius.
  const double margin = std::max(0.1, r / 3.0);
  int in_front = 0, behind = 0;
  for (const Vec3& p : pts) {
    const double range = p.norm(), cos_in = n.dot(p) / range;
    if (std::abs(cos_in) < 1e-6) continue;
    const double s = -d / cos_in;  // the ray's range at the plane
    if (s <= 0.0) continue;
    if (((s / range) * p - hole.center).squaredNorm() > 0.64 * r * r) continue;
    in_front += range < s - margin;
    behind += range > s + margin;
  }
  if (in_front < 10 || in_front <= behind) return {};
  std::ostringstream os;
  os << "the hole at " << hole.center.transpose() << " is a shadow: " << in_front
     << " points seen through it lie in front of the board (" << behind << " behind)";
  return os.str();
}

/// Fitted centres must reproduce the layout's pairwise distances. Empty when they do.
std::string check_layout(const std::vector<LidarHole>& holes, const std::vector<Vec2>& layout, double r,
                         const LidarDetectionOptions& options) {
  const double tol = std::max(options.layout_tolerance_m, 0.25 * r);
  for (std::size_t a = 0; a < holes.size(); ++a) {
    for (std::size_t b = a + 1; b < holes.size(); ++b) {
      const double fitted = (holes[a].center - holes[b].center).norm();
      const double expected = (layout[a] - layout[b]).norm();
      if (std::abs(fitted - expected) > tol) {
        std::ostringstream s;
        s << "holes " << a << " and " << b << " are " << fitted << " m apart, the layout says " << expected
          << " m (tolerance " << tol << " m)";
        return s.str();
      }
    }
  }
  return {};
}

std::string describe_profile(const BoardGeometry& g, bool has_ring, const EdgeSource& src,
                             const std::vector<LidarHole>& holes) {
  std::ostringstream s;
  s << g.q.size() << " board points, spacing " << g.spacing << " m, "
    << (has_ring ? "ring field" : src.use_lines ? "lines recovered from elevations" : "no scan lines");
  if (src.use_lines && !holes.empty()) {
    int lo = 1 << 30, hi = 0;
    for (const LidarHole& h : holes) {
      lo = std::min(lo, h.lines_across);
      hi = std::max(hi, h.lines_across);
    }
    s << ", " << lo << "-" << hi << " lines across a hole";
  }
  return s.str();
}

/// Holes in layout order -> row-major, top-left first (contracts.md).
std::vector<LidarHole> row_major(std::vector<LidarHole> holes, const std::vector<Vec2>& layout) {
  std::vector<std::size_t> order(layout.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (std::abs(layout[a].y() - layout[b].y()) > 1e-6) return layout[a].y() > layout[b].y();
    return layout[a].x() < layout[b].x();
  });
  std::vector<LidarHole> sorted;
  for (std::size_t k : order) sorted.push_back(std::move(holes[k]));
  return sorted;
}

/// Hole detection and fitting on one board segment C (board indices into pts).
BoardResult holes_on_board(const std::vector<Vec3>& pts, const std::vector<int>& board,
                           const std::vector<int>& rings, bool has_ring,
                           const core::TargetSpec& target, const LidarDetectionOptions& options) {
  BoardResult res;
  const double r = target.radius_m;
  if (static_cast<int>(board.size()) < options.min_board_points) {
    res.reason = "plane segment has " + std::to_string(board.size()) + " points, fewer than " +
                 std::to_string(options.min_board_points);
    return res;
  }
  res.plane = fit_plane(pts, board);
  const BoardGeometry g = board_geometry(pts, board, res.plane, options.up_lidar);
  const std::vector<Vec2> layout = target_layout(target);
  if (std::string why = check_board_extent(g.q, layout, target); !why.empty()) {
    res.reason = std::move(why);
    return res;
  }
  const double cell = options.grid_cell_m > 0 ? options.grid_cell_m : std::clamp(r / 12.0, 0.004, 0.03);
  std::vector<HoleCandidate> cand;
  for (const HoleCandidate& c : find_empty_discs(g.q, r, cell)) {
    if (enclosed(g.q, c.center, r)) cand.push_back(c);
  }
  const std::vector<Vec2> init = match_layout(layout, cand, r, &res.matched);
  if (init.empty()) {
    res.reason = "no enclosed empty disc of radius " + std::to_string(r) + " m in the layout (" +
                 std::to_string(cand.size()) + " candidate(s))";
    return res;
  }
  const EdgeSource src = choose_edge_source(pts, board, rings, has_ring, options);
  if (!src.reason.empty()) {
    res.reason = src.reason;
    return res;
  }
  std::vector<Vec3> line_edges;
  std::vector<int> line_ids;
  if (src.use_lines) line_edges = scan_line_edges(pts, board, src.lines, g.frame, options, &line_ids);
  bool fell_back = false;
  for (std::size_t h = 0; h < init.size(); ++h) {
    Vec2 c2 = init[h];
    std::vector<int> edge_lines;
    std::vector<Vec3> edges = hole_edges(line_edges, line_ids, g, r, options, src.use_lines, &c2, &edge_lines, &fell_back);
    if (static_cast<int>(edges.size()) < options.min_edge_points) {
      res.reason = "hole " + std::to_string(h) + ": " + std::to_string(edges.size()) + " edge points, fewer than " +
                   std::to_string(options.min_edge_points);
      return res;
    }
    res.holes.push_back(fit_hole(std::move(edges), edge_lines, g, c2, r));
    // The fit refines the empty disc it started from; a centre that wandered off it was
    // pulled by edges of something else.
    const double moved = (g.frame.to2d(res.holes.back().center) - init[h]).norm();
    if (moved > 0.5 * r) {
      std::ostringstream s;
      s << "hole " << h << ": the fitted centre moved " << moved << " m from the empty disc (limit " << 0.5 * r << " m)";
      res.reason = s.str();
      res.holes.clear();
      return res;
    }
  }
  // Holes of this target: the free radius and the residual must agree with the known radius
  // (rejects gaps, windows and shadows that happen to be empty discs).
  for (std::size_t h = 0; h < res.holes.size(); ++h) {
    const LidarHole& hole = res.holes[h];
    if (std::abs(hole.radius_m - r) > options.max_radius_error * r || hole.rms_m > options.max_rms_fraction * r) {
      std::ostringstream s;
      s << "hole " << h << ": fitted radius " << hole.radius_m << " m (rms " << hole.rms_m
        << " m) does not match the target radius " << r << " m";
      res.reason = s.str();
      res.holes.clear();
      return res;
    }
  }
  if (options.correct_edge_bias) correct_edge_bias(g, r, options, &res);
  if (!src.use_lines || fell_back) {
    for (const LidarHole& hole : res.holes) {
      if (std::string why = check_hole_surroundings(g, hole, r); !why.empty()) {
        res.reason = std::move(why);
        res.holes.clear();
        return res;
      }
    }
  }
  if (std::string why = check_layout(res.holes, layout, r, options); !why.empty()) {
    res.reason = std::move(why);
    res.holes.clear();
    return res;
  }
  // Last: one pass over the whole cloud per hole.
  for (const LidarHole& hole : res.holes) {
    if (std::string why = check_see_through(pts, hole, r); !why.empty()) {
      res.reason = std::move(why);
      res.shadow = true;
      res.holes.clear();
      return res;
    }
  }
  for (LidarHole& hole : res.holes) {
    res.score += (std::abs(hole.radius_m - r) + hole.rms_m) / r / static_cast<double>(init.size());
    hole.circle_points = sample_circle(hole.center, hole.normal, r, options.circle_step_deg);
  }
  res.method = src.method;
  if (src.use_lines) {
    int fewest = 1 << 30;
    for (const LidarHole& hole : res.holes) fewest = std::min(fewest, hole.lines_across);
    // 2-4 lines across a hole: the centre rests on a few chords of the known radius.
    if (fewest >= 1 && fewest <= 4) res.method = "sparse_lines" + src.method.substr(src.method.find(' '));
  }
  if (fell_back) res.method += "+occupancy";
  res.profile = describe_profile(g, has_ring, src, res.holes);
  res.spacing_m = g.spacing;
  res.holes = row_major(std::move(res.holes), layout);
  res.ok = true;
  return res;
}

/// The cloud's finite points within the options' range, with their rings.
struct RangedPoints {
  std::vector<Vec3> pts;
  std::vector<int> rings;
};

RangedPoints points_in_range(const cloud::Cloud& cloud, const LidarDetectionOptions& opt) {
  RangedPoints out;
  out.pts.reserve(cloud.size());
  for (const auto& p : cloud.points) {
    const Vec3 v(p.x, p.y, p.z);
    if (!v.allFinite()) continue;
    const double range = v.norm();
    if (range < opt.min_range_m || range > opt.max_range_m) continue;
    out.pts.push_back(v);
    out.rings.push_back(p.ring);
  }
  return out;
}

/// Half the diagonal of the target: its holes' extent, or its board's when that is larger.
double board_half_diagonal(const core::TargetSpec& target) {
  const std::vector<Vec2> layout = target_layout(target);
  double board_half_diag = 0.0;
  for (const Vec2& h : layout) {
    board_half_diag = std::max(board_half_diag, h.norm() + 2.0 * target.radius_m);
  }
  if (target.board_size_m) {
    board_half_diag = std::max(board_half_diag, 0.5 * target.board_size_m->norm());
  }
  return board_half_diag;
}

/// The detection of the board `b` found on `board` (indices into pts).
void take_board(const BoardResult& b, const std::vector<int>& board, const std::vector<Vec3>& pts,
                LidarTargetDetection* det) {
  det->ok = true;
  det->plane = b.plane;
  det->holes = b.holes;
  det->edge_method = b.method;
  det->cloud_profile = b.profile;
  det->point_spacing_m = b.spacing_m;
  det->edge_bias_m = b.edge_bias_m;
  det->edge_bias_source = b.edge_bias_source;
  for (int i : board) det->board_points.push_back(pts[static_cast<std::size_t>(i)]);
}

/// Algorithm 2's FR: the points within R of the seed, and the point nearest the seed.
struct SeedRegion {
  std::vector<int> fr;
  int nearest = -1;
  double nearest_d = 1e9;
};

SeedRegion seed_region(const std::vector<Vec3>& pts, const Vec3& seed, double R) {
  SeedRegion out;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double d = (pts[i] - seed).norm();
    if (d <= R) out.fr.push_back(static_cast<int>(i));
    if (d < out.nearest_d) {
      out.nearest_d = d;
      out.nearest = static_cast<int>(i);
    }
  }
  return out;
}

/// Algorithm 2, lines 1-5: planes of `fr`, largest first, until one holds `nearest`; its
/// inliers, or none.
std::vector<int> plane_through(const std::vector<Vec3>& pts, const std::vector<int>& fr,
                               int nearest, const LidarDetectionOptions& opt) {
  // The rest of a plane's complement is not a plane: a backdrop larger than the board is
  // often the first plane found, and the board is among what remains.
  std::vector<int> fg, rest = fr;
  for (int k = 0; k < 6 && rest.size() >= 3 && fg.empty(); ++k) {
    std::vector<int> in, out;
    if (!sac_plane(pts, rest, opt.sac_distance_m, &in, &out)) break;  // line 1
    if (std::find(in.begin(), in.end(), nearest) != in.end()) fg = std::move(in);
    rest = std::move(out);
  }
  return fg;
}

/// The part of a plane's inliers `fg` connected to `nearest`, or `fg` when that part has
/// fewer than 3 points.
std::vector<int> connected_part(const std::vector<Vec3>& pts, std::vector<int> fg, int nearest,
                                double board_half_diag) {
  // A plane's inliers also include unconnected surfaces it cuts (e.g. a strip of the
  // backdrop where the board's plane meets it, metres away), which would make the segment
  // far larger than the board. The tolerance bridges the gap between scan lines on the
  // board, not the gap to the backdrop.
  const double tolerance = std::max(0.15, 0.25 * board_half_diag);
  std::vector<int> part;
  for (auto& cluster : clusters_of(pts, fg, tolerance, 3)) {
    if (std::find(cluster.begin(), cluster.end(), nearest) != cluster.end()) {
      part = std::move(cluster);
      break;
    }
  }
  if (part.size() >= 3) fg = std::move(part);
  return fg;
}

/// Algorithm 2 with the clicked point: the board on the plane through the point nearest
/// the seed.
void detect_at_seed(const RangedPoints& in, bool has_ring, const core::TargetSpec& target,
                    const LidarDetectionOptions& opt, double board_half_diag, const Vec3& seed,
                    LidarTargetDetection* det) {
  const std::vector<Vec3>& pts = in.pts;
  // FR = points within R of the seed.
  const double R = opt.seed_radius_m > 0 ? opt.seed_radius_m : 2.0 * board_half_diag + 0.2;
  const SeedRegion region = seed_region(pts, seed, R);
  if (region.fr.size() < 3 || region.nearest_d > 0.5 * R) {
    det->reason = "no points near the seed (nearest at " + std::to_string(region.nearest_d) + " m)";
    return;
  }
  std::vector<int> fg = plane_through(pts, region.fr, region.nearest, opt);
  if (fg.empty()) {
    det->reason = "no plane through the point nearest the seed";
    return;
  }
  // Keep the part of that plane that contains the seed.
  fg = connected_part(pts, std::move(fg), region.nearest, board_half_diag);
  std::vector<int> c;
  if (!sac_plane(pts, fg, opt.refit_distance_m, &c, nullptr)) {  // line 6
    det->reason = "the seed's segment is not planar";
    return;
  }
  const BoardResult b = holes_on_board(pts, c, in.rings, has_ring, target, opt);
  if (!b.ok) {
    det->reason = "seeded board: " + b.reason;
    return;
  }
  take_board(b, c, pts, det);
}

/// The points' voxel centroids (PCL VoxelGrid).
std::vector<Vec3> voxel_downsample(const std::vector<Vec3>& pts, double voxel_m) {
  std::vector<int> every(pts.size());
  std::iota(every.begin(), every.end(), 0);
  const pcl::PointCloud<pcl::PointXYZ>::Ptr all = to_pcl(pts, every);
  pcl::VoxelGrid<pcl::PointXYZ> vg;
  vg.setInputCloud(all);
  vg.setLeafSize(static_cast<float>(voxel_m), static_cast<float>(voxel_m),
                 static_cast<float>(voxel_m));
  pcl::PointCloud<pcl::PointXYZ> out;
  vg.filter(out);
  std::vector<Vec3> ds;
  for (const auto& p : out.points) ds.emplace_back(p.x, p.y, p.z);
  return ds;
}

/// PCL's region growing on neighbour lists found beforehand. Its own search is the k nearest
/// neighbours of every point, the same lists as the normals' (same cloud, same k): given
/// them, the cloud needs one k-d tree and one search instead of two of each (the searches
/// are the largest part of a LIDAR detection).
class RegionGrowingOnNeighbours : public pcl::RegionGrowing<pcl::PointXYZ, pcl::Normal> {
 public:
  explicit RegionGrowingOnNeighbours(std::vector<pcl::Indices> neighbours) : given_(std::move(neighbours)) {}

 protected:
  // The base's checks without its tree, which it would build again over the same cloud.
  bool prepareForSegmentation() override {
    return !input_->points.empty() && normals_ && normals_->size() == input_->size() && neighbour_number_ > 0 &&
           given_.size() == input_->size();
  }
  void findPointNeighbours() override { point_neighbours_ = std::move(given_); }

 private:
  std::vector<pcl::Indices> given_;
};

/// Planar segments of the downsampled cloud by region growing on normals (PCL), largest
/// first: a small board in a large scene is rarely among the first planes a global RANSAC
/// finds.
std::vector<std::vector<int>> planar_segments(const std::vector<Vec3>& ds,
                                              const LidarDetectionOptions& opt) {
  const int min_ds_points = std::max(10, opt.min_board_points / 4);
  constexpr int kNeighbours = 12;
  std::vector<std::vector<int>> segments;
  // No segment could reach the minimum size (and PCL complains about a tree over nothing).
  if (ds.size() < static_cast<std::size_t>(min_ds_points)) return segments;
  std::vector<int> every(ds.size());
  std::iota(every.begin(), every.end(), 0);
  auto dpc = to_pcl(ds, every);
  // The normals as pcl::NormalEstimation computes them (its plane fit, turned towards the
  // sensor origin), on the neighbour lists the region growing then reuses.
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(dpc);
  std::vector<pcl::Indices> neighbours(dpc->size());
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  normals->resize(dpc->size());
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  const Eigen::Vector4f& origin = dpc->sensor_origin_;
  std::vector<float> d2;
  for (std::size_t i = 0; i < dpc->size(); ++i) {
    pcl::Normal& n = (*normals)[i];
    if (tree.nearestKSearch(static_cast<int>(i), kNeighbours, neighbours[i], d2) == 0 ||
        !ne.computePointNormal(*dpc, neighbours[i], n.normal_x, n.normal_y, n.normal_z, n.curvature)) {
      n.normal_x = n.normal_y = n.normal_z = n.curvature = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    pcl::flipNormalTowardsViewpoint((*dpc)[i], origin[0], origin[1], origin[2], n.normal_x, n.normal_y,
                                    n.normal_z);
  }
  RegionGrowingOnNeighbours rg(std::move(neighbours));
  rg.setMinClusterSize(min_ds_points);
  rg.setMaxClusterSize(static_cast<int>(ds.size()) + 1);
  rg.setNumberOfNeighbours(kNeighbours);
  rg.setInputCloud(dpc);
  rg.setInputNormals(normals);
  rg.setSmoothnessThreshold(static_cast<float>(opt.smoothness_deg * kPi / 180.0));
  rg.setCurvatureThreshold(0.05f);
  std::vector<pcl::PointIndices> found;
  rg.extract(found);
  for (const auto& f : found) segments.push_back(f.indices);
  std::sort(segments.begin(), segments.end(),
            [](const auto& x, const auto& y) { return x.size() > y.size(); });
  return segments;
}

/// The full-resolution points near a downsampled segment's plane, in its box grown by half
/// the board (region growing may stop at a noisy part of the board); false when the
/// segment is too small or too large for the board.
bool points_near_segment(const std::vector<Vec3>& pts, const std::vector<Vec3>& ds,
                         const std::vector<int>& seg, const core::TargetSpec& target,
                         const LidarDetectionOptions& opt, double board_half_diag,
                         std::vector<int>* full) {
  const Eigen::Vector4d plane = fit_plane(ds, seg);
  // Quick size test on the downsampled segment before touching the full cloud.
  Vec3 lo = ds[static_cast<std::size_t>(seg[0])], hi = lo;
  for (int i : seg) {
    lo = lo.cwiseMin(ds[static_cast<std::size_t>(i)]);
    hi = hi.cwiseMax(ds[static_cast<std::size_t>(i)]);
  }
  const double diag = (hi - lo).norm();
  const double max_diag =
      target.board_size_m ? 1.5 * target.board_size_m->norm() + 0.3 : 8.0 * board_half_diag + 1.0;
  if (diag < board_half_diag || diag > max_diag) return false;
  const double grow = 0.5 * board_half_diag + opt.search_voxel_m;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3& p = pts[i];
    if (std::abs(plane.head<3>().dot(p) + plane[3]) > 2.0 * opt.sac_distance_m) continue;
    if ((p.array() < lo.array() - grow).any() || (p.array() > hi.array() + grow).any()) continue;
    full->push_back(static_cast<int>(i));
  }
  return true;
}

/// The automatic search's outcome: the best board (most matched holes, then the lowest
/// score) and, when there is none, why the last segment tried failed.
struct BestBoard {
  BoardResult result;
  std::vector<int> board;  ///< indices into the points
  std::string last_reason = "no plane segment";
  std::string shadow;  ///< a hole-like gap rejected by check_see_through, if any
  std::size_t segments = 0;  ///< planar segments found
};

/// Planes of the cloud, largest first, found on a voxel-downsampled copy (for speed); each
/// plane split into Euclidean segments whose full-resolution points are then re-fitted
/// (Algorithm 2, line 6) and searched for the target's holes.
BestBoard best_board(const RangedPoints& in, bool has_ring, const core::TargetSpec& target,
                     const LidarDetectionOptions& opt, double board_half_diag) {
  const std::vector<Vec3>& pts = in.pts;
  const std::vector<Vec3> ds = voxel_downsample(pts, opt.search_voxel_m);
  const std::vector<std::vector<int>> segments = planar_segments(ds, opt);
  BestBoard best;
  best.segments = segments.size();
  for (const auto& seg : segments) {
    std::vector<int> full;
    if (!points_near_segment(pts, ds, seg, target, opt, board_half_diag, &full)) continue;
    std::vector<int> c;
    if (!sac_plane(pts, full, opt.refit_distance_m, &c, nullptr)) continue;
    const BoardResult b = holes_on_board(pts, c, in.rings, has_ring, target, opt);
    if (b.ok) {
      core::log_debug("calib_targets: board with ", b.matched, " matched holes, score ", b.score);
      if (!best.result.ok || b.matched > best.result.matched ||
          (b.matched == best.result.matched && b.score < best.result.score)) {
        best.result = b;
        best.board = c;
      }
      continue;
    }
    best.last_reason = b.reason;
    if (b.shadow) best.shadow = b.reason;
    core::log_debug("calib_targets: segment of ", c.size(), " points at ",
                    pts[static_cast<std::size_t>(c[0])].transpose(), ": ", b.reason);
  }
  return best;
}

}  // namespace

std::string LidarDetectionOptions::validate() const {
  std::ostringstream s;
  if (seed_radius_m < 0) s << "seed_radius_m = " << seed_radius_m << " must be >= 0; ";
  if (!(sac_distance_m > 0)) s << "sac_distance_m = " << sac_distance_m << " must be > 0; ";
  if (!(refit_distance_m > 0)) s << "refit_distance_m = " << refit_distance_m << " must be > 0; ";
  if (!(theta_gap_factor > 1)) s << "theta_gap_factor = " << theta_gap_factor << " must be > 1; ";
  if (!(smoothness_deg > 0)) s << "smoothness_deg = " << smoothness_deg << " must be > 0; ";
  if (!(max_range_m > min_range_m)) s << "max_range_m must exceed min_range_m; ";
  if (min_edge_points < 3) s << "min_edge_points = " << min_edge_points << " must be >= 3; ";
  if (grid_cell_m < 0) s << "grid_cell_m = " << grid_cell_m << " must be >= 0; ";
  if (!(search_voxel_m > 0)) s << "search_voxel_m = " << search_voxel_m << " must be > 0; ";
  if (!(max_radius_error > 0)) s << "max_radius_error must be > 0; ";
  if (!(max_rms_fraction > 0)) s << "max_rms_fraction must be > 0; ";
  if (!(circle_step_deg > 0 && circle_step_deg <= 90)) s << "circle_step_deg must be in (0, 90]; ";
  if (up_lidar.norm() < 1e-6) s << "up_lidar must be non-zero; ";
  if (!(beam_divergence_rad >= 0 && beam_divergence_rad < 0.1)) s << "beam_divergence_rad = " << beam_divergence_rad << " must be in [0, 0.1); ";
  if (!(layout_tolerance_m > 0)) s << "layout_tolerance_m = " << layout_tolerance_m << " must be > 0; ";
  return s.str();
}

std::vector<Eigen::Vector2d> target_layout(const core::TargetSpec& target) {
  if (target.holes_m.empty()) return {Eigen::Vector2d::Zero()};
  return target.holes_m;
}

Eigen::Vector3d fit_circle_center_in_plane(const std::vector<Eigen::Vector3d>& edge_points,
                                           const Eigen::Vector3d& normal,
                                           const Eigen::Vector3d& origin, double radius_m,
                                           const Eigen::Vector3d& initial_center,
                                           double* rms_m) {
  const Vec3 n = normal.normalized();
  const Vec3 ex = n.unitOrthogonal();
  const Vec3 ey = n.cross(ex);
  double ab[2] = {(initial_center - origin).dot(ex), (initial_center - origin).dot(ey)};
  ceres::Problem problem;
  for (const Vec3& p : edge_points) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CircleResidual, 1, 2>(
                                 new CircleResidual(p, origin, ex, ey, radius_m)),
                             nullptr, ab);
  }
  ceres::Solver::Options so;
  so.max_num_iterations = 100;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  const Vec3 c = origin + ab[0] * ex + ab[1] * ey;
  if (rms_m) {
    double s = 0.0;
    for (const Vec3& p : edge_points) {
      const Vec3 d = p - c;
      const double in_plane = (d - d.dot(n) * n).norm();
      s += (in_plane - radius_m) * (in_plane - radius_m);
    }
    *rms_m = edge_points.empty() ? 0.0 : std::sqrt(s / static_cast<double>(edge_points.size()));
  }
  return c;
}

std::vector<Eigen::Vector3d> sample_circle(const Eigen::Vector3d& center,
                                           const Eigen::Vector3d& normal, double radius_m,
                                           double step_deg) {
  // Algorithm 3, lines 5-14: a 2D circle mapped by the plane's orthonormal basis.
  const Vec3 n = normal.normalized();
  const Vec3 v1 = n.unitOrthogonal();
  const Vec3 v2 = n.cross(v1);
  std::vector<Vec3> out;
  const int count = static_cast<int>(std::round(360.0 / step_deg));
  out.reserve(static_cast<std::size_t>(count));
  for (int k = 0; k < count; ++k) {
    const double th = k * step_deg * kPi / 180.0;
    out.push_back(center + radius_m * (std::cos(th) * v1 + std::sin(th) * v2));
  }
  return out;
}

LidarTargetDetection detect_target_in_cloud(const cloud::Cloud& cloud, bool has_ring,
                                            const core::TargetSpec& target,
                                            const LidarDetectionOptions& options,
                                            std::optional<Eigen::Vector3d> seed) {
  if (const std::string err = options.validate(); !err.empty()) {
    throw std::invalid_argument("LidarDetectionOptions: " + err);
  }
  if (!(target.radius_m > 0)) {
    throw std::invalid_argument("TargetSpec: radius_m = " + std::to_string(target.radius_m) +
                                " must be > 0");
  }
  LidarTargetDetection det;
  if (cloud.empty()) {
    det.reason = "empty cloud";
    return det;
  }
  LidarDetectionOptions opt = options;
  opt.up_lidar = options.up_lidar.normalized();
  const RangedPoints in = points_in_range(cloud, opt);
  if (in.pts.size() < 3) {
    det.reason = "no points between " + std::to_string(opt.min_range_m) + " and " +
                 std::to_string(opt.max_range_m) + " m";
    return det;
  }
  const double board_half_diag = board_half_diagonal(target);
  if (seed) {
    detect_at_seed(in, has_ring, target, opt, board_half_diag, *seed, &det);
    return det;
  }
  const BestBoard best = best_board(in, has_ring, target, opt, board_half_diag);
  if (best.result.ok) {
    take_board(best.result, best.board, in.pts, &det);
    return det;
  }
  // Noisy dense clouds: normals over a few 5 cm voxels scatter by more than the smoothness
  // threshold (2 cm noise over 12 neighbours ~10 cm apart: ~10 deg) and region growing splits
  // the board. One retry with coarser voxels and twice the threshold; every check on the
  // board and its holes still applies.
  if (opt.search_voxel_m < 0.09) {
    LidarDetectionOptions coarser = options;
    coarser.search_voxel_m = 2.0 * opt.search_voxel_m;
    coarser.smoothness_deg = 2.0 * opt.smoothness_deg;
    LidarTargetDetection again = detect_target_in_cloud(cloud, has_ring, target, coarser);
    if (again.ok) return again;
  }
  det.reason = "no board with the target's holes found among " + std::to_string(best.segments) +
               " planar segments (last: " + best.last_reason + ")";
  if (!best.shadow.empty() && best.shadow != best.last_reason) det.reason += "; rejected: " + best.shadow;
  return det;
}

}  // namespace rgbdt::calib_targets
