#include "rgbdt/extrinsics/edge_distance_field.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace rgbdt::extrinsics {

namespace {

// One tile row of the nearest-point claim: node k (0..7) lies at du = u0 + k, dv^2 = dv2
// from point i, which takes the nodes it is strictly nearer to. SSE2 (every x86-64) does
// the 8 nodes in two steps; GCC does not vectorise the scalar loop's selects.
inline void claim_tile_row(float u0, float dv2, int i, float* d2s, int* owners) {
#if defined(__SSE2__)
  const __m128 v_dv2 = _mm_set1_ps(dv2), v_u0 = _mm_set1_ps(u0);
  const __m128i v_i = _mm_set1_epi32(i);
  for (int h = 0; h < 2; ++h) {
    const __m128 k = h == 0 ? _mm_setr_ps(0.f, 1.f, 2.f, 3.f) : _mm_setr_ps(4.f, 5.f, 6.f, 7.f);
    const __m128 du = _mm_add_ps(v_u0, k);
    const __m128 d2 = _mm_add_ps(_mm_mul_ps(du, du), v_dv2);
    const __m128 old = _mm_loadu_ps(d2s + 4 * h);
    const __m128i nearer = _mm_castps_si128(_mm_cmplt_ps(d2, old));
    _mm_storeu_ps(d2s + 4 * h, _mm_min_ps(d2, old));
    __m128i* owner = reinterpret_cast<__m128i*>(owners + 4 * h);
    const __m128i kept = _mm_andnot_si128(nearer, _mm_loadu_si128(owner));
    _mm_storeu_si128(owner, _mm_or_si128(kept, _mm_and_si128(nearer, v_i)));
  }
#else
  for (int k = 0; k < 8; ++k) {
    const float du = u0 + static_cast<float>(k);
    const float d2 = du * du + dv2;
    const bool nearer = d2 < d2s[k];
    d2s[k] = nearer ? d2 : d2s[k];
    owners[k] = nearer ? i : owners[k];
  }
#endif
}

/// The grid's bounding box: the edge points' with band_px + 2 px around [px].
struct GridBox {
  int col_begin = 0, row_begin = 0, cols = 0, rows = 0;
  // Grid pixel of point p, rounded (coordinates relative to the grid are >= margin > 0, so
  // truncating x + 0.5 rounds like lround, without the libm call).
  int pixel_c(const Eigen::Vector2d& p) const { return static_cast<int>(p.x() - col_begin + 0.5); }
  int pixel_r(const Eigen::Vector2d& p) const { return static_cast<int>(p.y() - row_begin + 0.5); }
};

/// Throws for non-finite points and for a box of more than max_nodes nodes.
GridBox band_box(const std::vector<Eigen::Vector2d>& edge_points_px,
                 const EdgeFieldOptions& options) {
  Eigen::Vector2d lo = edge_points_px.front(), hi = lo;
  for (const auto& p : edge_points_px) {
    if (!p.allFinite()) {
      throw std::invalid_argument("EdgeDistanceField: non-finite edge point");
    }
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double margin = options.band_px + 2.0;
  GridBox box;
  box.col_begin = static_cast<int>(std::floor(lo.x() - margin));
  box.row_begin = static_cast<int>(std::floor(lo.y() - margin));
  box.cols = static_cast<int>(std::ceil(hi.x() + margin)) - box.col_begin + 1;
  box.rows = static_cast<int>(std::ceil(hi.y() + margin)) - box.row_begin + 1;
  if (static_cast<long>(box.cols) * box.rows > options.max_nodes) {
    std::ostringstream os;
    os << "EdgeDistanceField: edge points span " << box.cols << " x " << box.rows
       << " px with the band, more than max_nodes = " << options.max_nodes
       << " (stray edge points far from the target?)";
    throw std::invalid_argument(os.str());
  }
  return box;
}

/// The points bucketed in 4 x 4 px cells for the neighbour searches, stored cell by cell
/// (row-major) so that the cells of one cell row are one contiguous run of points: a
/// search reads a few runs instead of chasing a list per cell. Within a cell the points
/// come in descending index: a fixed order, so that the normals' sums (and their
/// rounding) do not depend on how the points were listed within a cell.
class PointBuckets {
 public:
  PointBuckets(const std::vector<Eigen::Vector2d>& points, const GridBox& box)
      : box_(box), cell_cols_(box.cols / kCell + 1), cell_rows_(box.rows / kCell + 1) {
    const int n = static_cast<int>(points.size());
    std::vector<int> cell_of(n);
    start_.assign(static_cast<size_t>(cell_cols_) * cell_rows_ + 1, 0);
    for (int i = 0; i < n; ++i) {
      const int c = box.pixel_c(points[i]), r = box.pixel_r(points[i]);
      cell_of[i] = (r / kCell) * cell_cols_ + c / kCell;
      ++start_[cell_of[i] + 1];
    }
    for (size_t k = 1; k < start_.size(); ++k) start_[k] += start_[k - 1];
    sorted_.resize(n);
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (int i = n - 1; i >= 0; --i) sorted_[fill[cell_of[i]]++] = points[i];
  }
  // Calls fn(q) for (at least) every point q within `reach` px of grid pixel (c0, r0).
  template <typename Fn>
  void for_points_near(int c0, int r0, int reach, Fn&& fn) const {
    const int r_lo = std::max(0, r0 - reach) / kCell,
              r_hi = std::min(box_.rows - 1, r0 + reach) / kCell;
    const int c_lo = std::max(0, c0 - reach) / kCell,
              c_hi = std::min(box_.cols - 1, c0 + reach) / kCell;
    for (int r = r_lo; r <= r_hi; ++r) {
      const size_t row = static_cast<size_t>(r) * cell_cols_;
      for (int j = start_[row + c_lo]; j < start_[row + c_hi + 1]; ++j) fn(sorted_[j]);
    }
  }

 private:
  static constexpr int kCell = 4;
  GridBox box_;
  int cell_cols_, cell_rows_;
  std::vector<int> start_;                // points of cell k: sorted_[start_[k] .. start_[k + 1])
  std::vector<Eigen::Vector2d> sorted_;  // the points, cell by cell
};

/// The neighbours of a point within a radius: their count and the sums of q and q q^T
/// over their offsets q from it.
struct NeighbourSums {
  double count = 0.0, x = 0.0, y = 0.0, xx = 0.0, xy = 0.0, yy = 0.0;
};

NeighbourSums neighbour_sums(const PointBuckets& buckets, const GridBox& box,
                             const Eigen::Vector2d& p, int reach, double radius2) {
  NeighbourSums s;
#if defined(__SSE2__)
  // Packed (x, y), (xx, yy), (xy, count). A candidate outside the radius adds zeros
  // (x + 0 == x), so the sums are the scalar ones, without a branch to mispredict on the
  // half of the candidates that lie outside (GCC turns the scalar select into one).
  const __m128d origin = _mm_loadu_pd(p.data()), r2 = _mm_set1_pd(radius2);
  const __m128d one = _mm_set1_pd(1.0);
  __m128d sum_q = _mm_setzero_pd(), sum_qq = sum_q, sum_xy_count = sum_q;
  buckets.for_points_near(box.pixel_c(p), box.pixel_r(p), reach, [&](const Eigen::Vector2d& point) {
    const __m128d q = _mm_sub_pd(_mm_loadu_pd(point.data()), origin);  // relative: no cancellation
    const __m128d qq = _mm_mul_pd(q, q);
    const __m128d in = _mm_cmple_pd(_mm_add_pd(qq, _mm_shuffle_pd(qq, qq, 1)), r2);
    const __m128d xy = _mm_mul_pd(q, _mm_shuffle_pd(q, q, 1));
    sum_q = _mm_add_pd(sum_q, _mm_and_pd(in, q));
    sum_qq = _mm_add_pd(sum_qq, _mm_and_pd(in, qq));
    sum_xy_count = _mm_add_pd(sum_xy_count, _mm_and_pd(in, _mm_unpacklo_pd(xy, one)));
  });
  s.x = _mm_cvtsd_f64(sum_q);
  s.y = _mm_cvtsd_f64(_mm_unpackhi_pd(sum_q, sum_q));
  s.xx = _mm_cvtsd_f64(sum_qq);
  s.yy = _mm_cvtsd_f64(_mm_unpackhi_pd(sum_qq, sum_qq));
  s.xy = _mm_cvtsd_f64(sum_xy_count);
  s.count = _mm_cvtsd_f64(_mm_unpackhi_pd(sum_xy_count, sum_xy_count));
#else
  buckets.for_points_near(box.pixel_c(p), box.pixel_r(p), reach, [&](const Eigen::Vector2d& point) {
    const double qx = point.x() - p.x(), qy = point.y() - p.y();  // relative: no cancellation
    if (qx * qx + qy * qy > radius2) return;
    s.count += 1.0;
    s.x += qx;
    s.y += qy;
    s.xx += qx * qx;
    s.xy += qx * qy;
    s.yy += qy * qy;
  });
#endif
  return s;
}

/// Edge normals: smallest principal direction of the neighbours within normal_radius_px
/// (zero where there is no line: isolated points, blobs).
std::vector<Eigen::Vector2d> edge_normals(const std::vector<Eigen::Vector2d>& edge_points_px,
                                          const GridBox& box, const EdgeFieldOptions& options) {
  const PointBuckets buckets(edge_points_px, box);
  const int n = static_cast<int>(edge_points_px.size());
  std::vector<Eigen::Vector2d> normals(n, Eigen::Vector2d::Zero());
  const int reach = static_cast<int>(std::ceil(options.normal_radius_px));
  const double radius2 = options.normal_radius_px * options.normal_radius_px;
  // All sums first, then the normals: the normals' divisions and square roots of
  // successive points then overlap instead of waiting behind each point's search.
  std::vector<NeighbourSums> sums(n);
  for (int i = 0; i < n; ++i) sums[i] = neighbour_sums(buckets, box, edge_points_px[i], reach, radius2);
  for (int i = 0; i < n; ++i) {
    const NeighbourSums& s = sums[i];
    if (s.count < 3.0) continue;  // isolated point: distance to the point itself
    // Scatter about the mean: a, b; b, c.
    const double mx = s.x / s.count, my = s.y / s.count;
    const double a = s.xx / s.count - mx * mx, b = s.xy / s.count - mx * my,
                 c = s.yy / s.count - my * my;
    // Eigen-decomposition of the symmetric 2x2 scatter in closed form.
    const double half_diff = 0.5 * (a - c), root = std::sqrt(half_diff * half_diff + b * b);
    const double l_max = 0.5 * (a + c) + root, l_min = 0.5 * (a + c) - root;
    // A line needs one dominant direction; a blob of points has none.
    if (l_max < 4.0 * l_min) continue;
    // Eigenvector of l_min: either row of (scatter - l_min I), rotated; take the better one.
    const Eigen::Vector2d v1(b, l_min - a), v2(l_min - c, b);
    const Eigen::Vector2d v = v1.squaredNorm() >= v2.squaredNorm() ? v1 : v2;
    if (v.squaredNorm() == 0.0) continue;  // all neighbours coincide: no direction
    normals[i] = v.normalized();
  }
  return normals;
}

/// A point's (2 band + 1)^2 square of grid pixels, clipped to the grid.
struct Square {
  int c_lo, c_hi, r_lo, r_hi;
};

std::vector<Square> band_squares(const std::vector<Eigen::Vector2d>& edge_points_px,
                                 const GridBox& box, int band) {
  std::vector<Square> squares(edge_points_px.size());
  for (size_t i = 0; i < edge_points_px.size(); ++i) {
    const int c0 = box.pixel_c(edge_points_px[i]), r0 = box.pixel_r(edge_points_px[i]);
    squares[i] = {std::max(0, c0 - band), std::min(box.cols - 1, c0 + band), std::max(0, r0 - band),
                  std::min(box.rows - 1, r0 + band)};
  }
  return squares;
}

/// The tiles of 2^shift x 2^shift nodes over the box; slot maps a tile to its block of
/// stored nodes, or -1.
struct TileLayout {
  int shift = 0, cols = 0, rows = 0, count = 0;
  std::vector<int> slot;
  int size() const { return 1 << shift; }
  int nodes() const { return size() * size(); }
};

/// Tiles that hold band nodes: those overlapping some point's square.
TileLayout band_tiles(const std::vector<Square>& squares, const GridBox& box, int shift) {
  TileLayout tiles;
  tiles.shift = shift;
  tiles.cols = (box.cols + tiles.size() - 1) >> shift;
  tiles.rows = (box.rows + tiles.size() - 1) >> shift;
  tiles.slot.assign(static_cast<size_t>(tiles.cols) * tiles.rows, -1);
  for (const Square& q : squares) {
    for (int tr = q.r_lo >> shift; tr <= q.r_hi >> shift; ++tr)
      for (int tc = q.c_lo >> shift; tc <= q.c_hi >> shift; ++tc)
        tiles.slot[static_cast<size_t>(tr) * tiles.cols + tc] = 0;
  }
  for (int& slot : tiles.slot) slot = slot == 0 ? tiles.count++ : -1;
  return tiles;
}

/// Per stored node: the edge point that claimed it (-1: none) and the squared distance.
struct NearestClaims {
  std::vector<int> nearest;
  std::vector<float> nearest_d2;
};

/// Exact nearest edge point of every node within band_px of an edge: each point claims
/// the nodes of its square that it is nearest to (ties to the lower index). The square's
/// rows are widened to whole tile rows (8 contiguous nodes, vectorised); nodes claimed
/// from beyond band_px are dropped later (their nearest point may not have visited them).
NearestClaims claim_nearest(const std::vector<Eigen::Vector2d>& edge_points_px, const GridBox& box,
                            const std::vector<Square>& squares, const TileLayout& tiles) {
  const size_t num_nodes = static_cast<size_t>(tiles.count) * tiles.nodes();
  NearestClaims claims;
  claims.nearest.assign(num_nodes, -1);
  claims.nearest_d2.assign(num_nodes, std::numeric_limits<float>::infinity());
  const int shift = tiles.shift;
  const int n = static_cast<int>(edge_points_px.size());
  for (int i = 0; i < n; ++i) {
    // Relative to the grid origin, so that float keeps ~1e-5 px.
    const float pu = static_cast<float>(edge_points_px[i].x() - box.col_begin);
    const float pv = static_cast<float>(edge_points_px[i].y() - box.row_begin);
    const Square& q = squares[i];
    for (int r = q.r_lo; r <= q.r_hi; ++r) {
      const float dv = static_cast<float>(r) - pv;
      const float dv2 = dv * dv;
      const size_t tile_row = static_cast<size_t>(r >> shift) * tiles.cols;
      const int row_in_tile = (r & (tiles.size() - 1)) << shift;
      for (int tc = q.c_lo >> shift; tc <= q.c_hi >> shift; ++tc) {
        const size_t base =
            static_cast<size_t>(tiles.slot[tile_row + tc]) * tiles.nodes() + row_in_tile;
        float* d2s = claims.nearest_d2.data() + base;
        int* owners = claims.nearest.data() + base;
        claim_tile_row(static_cast<float>(tc << shift) - pu, dv2, i, d2s, owners);
      }
    }
  }
  return claims;
}

/// The stored nodes' offsets to their nearest edge (*data, interleaved du, dv) and whether
/// each is inner (*inner); nodes beyond band_px are zero. The nodes are visited in storage
/// order (tile by tile), so no tile of the bounding box is looked up twice.
void store_offsets(const std::vector<Eigen::Vector2d>& edge_points_px,
                   const std::vector<Eigen::Vector2d>& normals, const GridBox& box,
                   const TileLayout& tiles, const NearestClaims& claims,
                   const EdgeFieldOptions& options, std::vector<float>* data,
                   std::vector<uint8_t>* inner) {
  const int shift = tiles.shift, tile_nodes = tiles.nodes(), mask = tiles.size() - 1;
  const double band2 = options.band_px * options.band_px;
  // A node is "inner" when the whole 4x4 bicubic stencil around it lies in the band.
  const float inner_d2 = static_cast<float>((options.band_px - 3.0) * (options.band_px - 3.0));
  std::vector<Eigen::Vector2i> tile_origin(tiles.count);  // pixel of each slot's first node
  for (int tr = 0; tr < tiles.rows; ++tr)
    for (int tc = 0; tc < tiles.cols; ++tc)
      if (const int slot = tiles.slot[static_cast<size_t>(tr) * tiles.cols + tc]; slot >= 0)
        tile_origin[slot] = {(tc << shift) + box.col_begin, (tr << shift) + box.row_begin};
  data->resize(2 * static_cast<size_t>(tiles.count) * tile_nodes);
  inner->resize(static_cast<size_t>(tiles.count) * tile_nodes);
  for (int slot = 0; slot < tiles.count; ++slot) {
    for (int k = 0; k < tile_nodes; ++k) {
      const size_t idx = static_cast<size_t>(slot) * tile_nodes + k;
      // Unclaimed nodes hold d2 = inf: neither in the band nor inner.
      const float d2 = claims.nearest_d2[idx];
      (*inner)[idx] = d2 <= inner_d2;
      double ou = 0.0, ov = 0.0;
      if (d2 <= band2) {
        // The tangent-line offset, except beyond the end of an open edge (where the tangent
        // line would continue the edge into empty space) and at isolated points (zero normal).
        const int best = claims.nearest[idx];
        ou = tile_origin[slot].x() + (k & mask) - edge_points_px[best].x();
        ov = tile_origin[slot].y() + (k >> shift) - edge_points_px[best].y();
        const double nu = normals[best].x(), nv = normals[best].y();
        if (nu * nu + nv * nv >= 0.5 && std::abs(ou * -nv + ov * nu) <= options.normal_radius_px) {
          const double along = ou * nu + ov * nv;
          ou = along * nu;
          ov = along * nv;
        }
      }
      (*data)[2 * idx] = static_cast<float>(ou);
      (*data)[2 * idx + 1] = static_cast<float>(ov);
    }
  }
}

/// The points bucketed in cell-px cells over the box (CSR, ascending index per cell).
struct SearchIndex {
  int cols = 0, rows = 0;
  std::vector<int> start, index;
};

SearchIndex search_index(const std::vector<Eigen::Vector2d>& points, const GridBox& box, int cell) {
  const int n = static_cast<int>(points.size());
  SearchIndex s;
  s.cols = box.cols / cell + 1;
  s.rows = box.rows / cell + 1;
  std::vector<int> cell_of(n);
  s.start.assign(static_cast<size_t>(s.cols) * s.rows + 1, 0);
  for (int i = 0; i < n; ++i) {
    // Relative coordinates are positive: truncation is floor.
    const int c = static_cast<int>(points[i].x() - box.col_begin) / cell;
    const int r = static_cast<int>(points[i].y() - box.row_begin) / cell;
    cell_of[i] = r * s.cols + c;
    ++s.start[cell_of[i] + 1];
  }
  for (size_t k = 1; k < s.start.size(); ++k) s.start[k] += s.start[k - 1];
  s.index.resize(n);
  std::vector<int> fill(s.start.begin(), s.start.end() - 1);
  for (int i = 0; i < n; ++i) s.index[fill[cell_of[i]]++] = i;  // ascending i per cell
  return s;
}

}  // namespace

std::string EdgeFieldOptions::validate() const {
  std::ostringstream os;
  if (!(band_px >= 5.0)) os << "band_px = " << band_px << ", expected >= 5; ";
  if (!(normal_radius_px > 0.5))
    os << "normal_radius_px = " << normal_radius_px << ", expected > 0.5; ";
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
  const GridBox box = band_box(edge_points_px, options);
  col_begin_ = box.col_begin;
  row_begin_ = box.row_begin;
  cols_ = box.cols;
  rows_ = box.rows;
  std::vector<Eigen::Vector2d> normals = edge_normals(edge_points_px, box, options);

  const int band = static_cast<int>(std::ceil(options.band_px));
  const std::vector<Square> squares = band_squares(edge_points_px, box, band);
  TileLayout tiles = band_tiles(squares, box, kTileShift);
  // Exact nearest edge point of every node within band_px of an edge (claim_nearest);
  // rows of 8 contiguous nodes are claimed at once.
  static_assert(kTile == 8, "claim_tile_row() handles rows of 8 nodes");
  const NearestClaims claims = claim_nearest(edge_points_px, box, squares, tiles);
  tangent_reach_px_ = options.normal_radius_px;
  store_offsets(edge_points_px, normals, box, tiles, claims, options, &data_, &inner_);
  tile_cols_ = tiles.cols;
  tile_rows_ = tiles.rows;
  tile_slot_ = std::move(tiles.slot);
  points_ = edge_points_px;
  normals_ = std::move(normals);

  SearchIndex search = search_index(points_, box, kSearchCell);
  search_cols_ = search.cols;
  search_rows_ = search.rows;
  search_start_ = std::move(search.start);
  search_index_ = std::move(search.index);
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
  double f[2];
  interpolate(px.x(), px.y(), f, nullptr, nullptr);
  return {f[0], f[1]};
}

}  // namespace rgbdt::extrinsics
