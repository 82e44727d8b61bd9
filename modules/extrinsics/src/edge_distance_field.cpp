#include "rgbdt/extrinsics/edge_distance_field.hpp"

#include <ceres/cubic_interpolation.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace rgbdt::extrinsics {

namespace {

// Tangent-line offset, except beyond the end of an open edge, where the tangent line would
// continue the edge into empty space, and at isolated points (zero normal).
Eigen::Vector2d offset_from(const Eigen::Vector2d& x, const Eigen::Vector2d& p,
                            const Eigen::Vector2d& n, double tangent_reach_px) {
  const Eigen::Vector2d d = x - p;
  if (n.squaredNorm() < 0.5) return d;
  if (std::abs(d.x() * -n.y() + d.y() * n.x()) > tangent_reach_px) return d;
  return d.dot(n) * n;
}

}  // namespace

std::string EdgeFieldOptions::validate() const {
  std::ostringstream os;
  if (!(band_px >= 5.0)) os << "band_px = " << band_px << ", expected >= 5; ";
  if (!(normal_radius_px > 0.5)) os << "normal_radius_px = " << normal_radius_px << ", expected > 0.5; ";
  if (max_nodes < 16) os << "max_nodes = " << max_nodes << ", expected >= 16; ";
  return os.str();
}

EdgeDistanceField::EdgeDistanceField(const std::vector<Eigen::Vector2d>& edge_points_px,
                                     const EdgeFieldOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("EdgeDistanceField: invalid options: " + why);
  }
  if (edge_points_px.empty()) {
    throw std::invalid_argument("EdgeDistanceField: no edge points (expected at least one)");
  }
  Eigen::Vector2d lo = edge_points_px.front(), hi = lo;
  for (const auto& p : edge_points_px) {
    if (!p.allFinite()) {
      throw std::invalid_argument("EdgeDistanceField: non-finite edge point");
    }
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = options.band_px + 2.0;
  col_begin_ = static_cast<int>(std::floor(lo.x() - margin));
  row_begin_ = static_cast<int>(std::floor(lo.y() - margin));
  cols_ = static_cast<int>(std::ceil(hi.x() + margin)) - col_begin_ + 1;
  rows_ = static_cast<int>(std::ceil(hi.y() + margin)) - row_begin_ + 1;
  if (static_cast<long>(cols_) * rows_ > options.max_nodes) {
    std::ostringstream os;
    os << "EdgeDistanceField: edge points span " << cols_ << " x " << rows_
       << " px with the band, more than max_nodes = " << options.max_nodes
       << " (stray edge points far from the target?)";
    throw std::invalid_argument(os.str());
  }
  const int n = static_cast<int>(edge_points_px.size());

  // Bucket the points in 4 x 4 px cells (linked lists), for the neighbour searches.
  constexpr int kCell = 4;
  const int cell_cols = cols_ / kCell + 1, cell_rows = rows_ / kCell + 1;
  std::vector<int> head(static_cast<size_t>(cell_cols) * cell_rows, -1), next(n, -1);
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(std::lround(edge_points_px[i].x())) - col_begin_;
    const int r = static_cast<int>(std::lround(edge_points_px[i].y())) - row_begin_;
    const size_t idx = static_cast<size_t>(r / kCell) * cell_cols + c / kCell;
    next[i] = head[idx];
    head[idx] = i;
  }
  // Calls fn(i) for (at least) every point within `reach` px of grid pixel (c0, r0).
  auto for_points_near = [&](int c0, int r0, int reach, auto&& fn) {
    const int r_lo = std::max(0, r0 - reach) / kCell, r_hi = std::min(rows_ - 1, r0 + reach) / kCell;
    const int c_lo = std::max(0, c0 - reach) / kCell, c_hi = std::min(cols_ - 1, c0 + reach) / kCell;
    for (int r = r_lo; r <= r_hi; ++r) {
      for (int c = c_lo; c <= c_hi; ++c) {
        for (int i = head[static_cast<size_t>(r) * cell_cols + c]; i >= 0; i = next[i]) fn(i);
      }
    }
  };

  // Edge normals: smallest principal direction of the neighbours within normal_radius_px.
  std::vector<Eigen::Vector2d> normals(n, Eigen::Vector2d::Zero());
  const int reach = static_cast<int>(std::ceil(options.normal_radius_px));
  const double radius2 = options.normal_radius_px * options.normal_radius_px;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = edge_points_px[i];
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    int count = 0;
    for_points_near(static_cast<int>(std::lround(p.x())) - col_begin_,
                    static_cast<int>(std::lround(p.y())) - row_begin_, reach, [&](int j) {
                      const Eigen::Vector2d& q = edge_points_px[j];
                      if ((q - p).squaredNorm() > radius2) return;
                      mean += q;
                      scatter += q * q.transpose();
                      ++count;
                    });
    if (count < 3) continue;  // isolated point: distance to the point itself
    mean /= count;
    scatter = scatter / count - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
    // A line needs one dominant direction; a blob of points has none.
    if (eig.eigenvalues()(1) < 4.0 * eig.eigenvalues()(0)) continue;
    normals[i] = eig.eigenvectors().col(0);
  }

  // Exact nearest edge point of every node within band_px of an edge: each point claims
  // the nodes of its (2 band + 1)^2 square that it is nearest to.
  std::vector<int> nearest(static_cast<size_t>(cols_) * rows_, -1);
  std::vector<float> nearest_d2(nearest.size(), std::numeric_limits<float>::infinity());
  const int band = static_cast<int>(std::ceil(options.band_px));
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& p = edge_points_px[i];
    const int c0 = static_cast<int>(std::lround(p.x())) - col_begin_;
    const int r0 = static_cast<int>(std::lround(p.y())) - row_begin_;
    for (int r = std::max(0, r0 - band); r <= std::min(rows_ - 1, r0 + band); ++r) {
      const double dy = r + row_begin_ - p.y();
      for (int c = std::max(0, c0 - band); c <= std::min(cols_ - 1, c0 + band); ++c) {
        const double dx = c + col_begin_ - p.x();
        const float d2 = static_cast<float>(dx * dx + dy * dy);
        const size_t idx = static_cast<size_t>(r) * cols_ + c;
        if (d2 < nearest_d2[idx]) {
          nearest_d2[idx] = d2;
          nearest[idx] = i;
        }
      }
    }
  }
  // A node is "inner" when the whole 4x4 bicubic stencil around it lies in the band.
  const float inner_d2 = static_cast<float>((options.band_px - 3.0) * (options.band_px - 3.0));
  data_.assign(nearest.size() * 2, 0.0f);
  inner_.assign(nearest.size(), 0);
  tangent_reach_px_ = options.normal_radius_px;
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      const size_t idx = static_cast<size_t>(r) * cols_ + c;
      const int best = nearest[idx];
      if (best < 0) continue;
      const Eigen::Vector2d x(c + col_begin_, r + row_begin_);
      const Eigen::Vector2d offset = offset_from(x, edge_points_px[best], normals[best],
                                                  options.normal_radius_px);
      data_[2 * idx] = static_cast<float>(offset.x());
      data_[2 * idx + 1] = static_cast<float>(offset.y());
      inner_[idx] = nearest_d2[idx] <= inner_d2;
    }
  }
  points_ = edge_points_px;
  normals_ = std::move(normals);

  search_cols_ = cols_ / kSearchCell + 1;
  search_rows_ = rows_ / kSearchCell + 1;
  std::vector<int> cell_of(n);
  search_start_.assign(static_cast<size_t>(search_cols_) * search_rows_ + 1, 0);
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(std::floor(points_[i].x() - col_begin_)) / kSearchCell;
    const int r = static_cast<int>(std::floor(points_[i].y() - row_begin_)) / kSearchCell;
    cell_of[i] = r * search_cols_ + c;
    ++search_start_[cell_of[i] + 1];
  }
  for (size_t k = 1; k < search_start_.size(); ++k) search_start_[k] += search_start_[k - 1];
  search_index_.resize(n);
  std::vector<int> fill(search_start_.begin(), search_start_.end() - 1);
  for (int i = 0; i < n; ++i) search_index_[fill[cell_of[i]]++] = i;  // ascending i per cell
}

void EdgeDistanceField::nearest_edge(const Eigen::Vector2d& px, Eigen::Vector2d* point,
                                     Eigen::Vector2d* normal) const {
  // Rings of cells around the (clamped) cell of px, until no unsearched cell can hold a
  // nearer point. Ties go to the lower index, as a linear scan would.
  const double x = px.x() - col_begin_, y = px.y() - row_begin_;
  const int c0 = std::clamp(static_cast<int>(std::floor(x / kSearchCell)), 0, search_cols_ - 1);
  const int r0 = std::clamp(static_cast<int>(std::floor(y / kSearchCell)), 0, search_rows_ - 1);
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  auto scan_cell = [&](int c, int r) {
    const size_t k = static_cast<size_t>(r) * search_cols_ + c;
    for (int j = search_start_[k]; j < search_start_[k + 1]; ++j) {
      const int i = search_index_[j];
      const double d2 = (px - points_[i]).squaredNorm();
      if (d2 < best_d2 || (d2 == best_d2 && i < best)) {
        best_d2 = d2;
        best = i;
      }
    }
  };
  for (int ring = 0;; ++ring) {
    const int c_lo = c0 - ring, c_hi = c0 + ring, r_lo = r0 - ring, r_hi = r0 + ring;
    for (int r = std::max(0, r_lo); r <= std::min(search_rows_ - 1, r_hi); ++r) {
      if (r == r_lo || r == r_hi) {
        for (int c = std::max(0, c_lo); c <= std::min(search_cols_ - 1, c_hi); ++c) scan_cell(c, r);
      } else {
        if (c_lo >= 0) scan_cell(c_lo, r);
        if (c_hi < search_cols_ && c_hi != c_lo) scan_cell(c_hi, r);
      }
    }
    // Lower bound on the distance from px to any cell outside the searched square.
    double bound = std::numeric_limits<double>::infinity();
    if (c_lo > 0) bound = std::min(bound, std::max(0.0, x - double(c_lo) * kSearchCell));
    if (r_lo > 0) bound = std::min(bound, std::max(0.0, y - double(r_lo) * kSearchCell));
    if (c_hi < search_cols_ - 1) bound = std::min(bound, std::max(0.0, double(c_hi + 1) * kSearchCell - x));
    if (r_hi < search_rows_ - 1) bound = std::min(bound, std::max(0.0, double(r_hi + 1) * kSearchCell - y));
    if (std::isinf(bound)) break;  // every cell searched
    if (best >= 0 && bound * bound > best_d2) break;
  }
  *point = points_[best];
  *normal = normals_[best];
  const Eigen::Vector2d d = px - *point;
  if (std::abs(d.x() * -normal->y() + d.y() * normal->x()) > tangent_reach_px_) normal->setZero();
}

Eigen::Vector2d EdgeDistanceField::offset(const Eigen::Vector2d& px) const {
  if (!in_band(px.x(), px.y())) {
    Eigen::Vector2d p, n;
    nearest_edge(px, &p, &n);
    return n.squaredNorm() > 0.5 ? Eigen::Vector2d((px - p).dot(n) * n) : Eigen::Vector2d(px - p);
  }
  const ceres::Grid2D<float, 2> grid(data_.data(), row_begin_, row_begin_ + rows_, col_begin_,
                                     col_begin_ + cols_);
  const ceres::BiCubicInterpolator<ceres::Grid2D<float, 2>> interpolator(grid);
  double f[2];
  interpolator.Evaluate(px.y(), px.x(), f);
  return {f[0], f[1]};
}

}  // namespace rgbdt::extrinsics
