#pragma once
/// \file
/// A smooth, exact distance field to sub-pixel image edge points: the image term of
/// Eq. (2) without the pixel quantisation of a distance transform.
///
/// Each grid node stores the vector from the edge curve to the node, ((x - p) . n) n,
/// where p is the nearest edge point and n the edge normal at p (PCA of its neighbours).
/// Its norm is the distance to the local tangent line of the edge, which equals the
/// distance to the curve up to O(spacing^2 * curvature), and it is linear across the edge,
/// so bicubic interpolation reproduces it exactly near the edge (a sampled |d| would be
/// biased by up to ~0.15 px towards the grid nodes). The grid is filled only in a narrow
/// band around the edges, stored in 8 x 8 node tiles that hold band nodes (cheap to build);
/// outside the band the same quantity is computed exactly from the nearest edge point (a
/// ring search over 16 px cells), so points projected far from the target, even outside
/// the image, still feel the true distance and its gradient.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace rgbdt::extrinsics {

struct EdgeFieldOptions {
  /// Half-width of the interpolated band around the edges [px]; bicubic is used within
  /// band_px - 3 of an edge. Points beyond it use the exact nearest-point form (slower per
  /// evaluation, same values), so this only trades build time against evaluation time;
  /// raise it when residuals stay large (noisy edges).
  double band_px = 5.0;
  /// Neighbourhood radius for the edge normals [px]; raise it for noisy edge points.
  double normal_radius_px = 3.0;
  /// Refuse grids with more nodes than this (guards against stray far-away edge points).
  long max_nodes = 8'000'000;
  std::string validate() const;  ///< empty when valid, else the reason
};

class EdgeDistanceField {
 public:
  /// Throws std::invalid_argument for an empty edge set, non-finite points or invalid
  /// options.
  explicit EdgeDistanceField(const std::vector<Eigen::Vector2d>& edge_points_px,
                             const EdgeFieldOptions& options = {});

  /// The band as a grid for ceres::BiCubicInterpolator (row = v, column = u [px]). Nodes
  /// outside the band read as zero, so interpolate only where in_band() holds (there the
  /// whole 4x4 stencil lies in the band).
  struct Grid {
    enum { DATA_DIMENSION = 2 };
    const EdgeDistanceField* field;
    void GetValue(int v, int u, double* f) const { field->node_value(v, u, f); }
  };
  Grid grid() const { return Grid{this}; }

  /// True when the bicubic stencil at the pixel lies in the filled band.
  bool in_band(double u, double v) const {
    // Range check in double first: far-off or non-finite projections must not reach the
    // integer conversion.
    const double x = u - col_begin_ + 0.5, y = v - row_begin_ + 0.5;
    if (!(x >= 0.0 && y >= 0.0 && x < cols_ && y < rows_)) return false;
    const long idx = node_index(static_cast<int>(y), static_cast<int>(x));
    return idx >= 0 && inner_[static_cast<size_t>(idx)];
  }
  /// Offset stored at grid node (v, u) [px], zero outside the band.
  void node_value(int v, int u, double* f) const {
    const int r = v - row_begin_, c = u - col_begin_;
    const long idx = (r >= 0 && c >= 0 && r < rows_ && c < cols_) ? node_index(r, c) : -1;
    f[0] = idx >= 0 ? data_[2 * static_cast<size_t>(idx)] : 0.0;
    f[1] = idx >= 0 ? data_[2 * static_cast<size_t>(idx) + 1] : 0.0;
  }
  /// Nodes stored (the tiles that hold the band), for tests and memory accounting.
  long num_stored_nodes() const { return static_cast<long>(inner_.size()); }

  /// Bicubic (Catmull-Rom) interpolation of the band at (u, v), the interpolant of
  /// ceres::BiCubicInterpolator over grid(), with its gradient, in one pass over the 4x4
  /// stencil. Call only where in_band(u, v) holds.
  inline void interpolate(double u, double v, double f[2], double df_du[2], double df_dv[2]) const
      __attribute__((always_inline));
  /// The offset vector at a pixel: bicubic inside the band, exact outside.
  Eigen::Vector2d offset(const Eigen::Vector2d& px) const;
  /// Exact form at any pixel: the nearest edge point and its unit normal; the normal is
  /// zero where the point-to-point offset applies (isolated points, beyond an edge's end).
  /// offset = ((px - point) . normal) normal, or px - point when the normal is zero.
  void nearest_edge(const Eigen::Vector2d& px, Eigen::Vector2d* point,
                    Eigen::Vector2d* normal) const;
  double distance_px(const Eigen::Vector2d& px) const { return offset(px).norm(); }

 private:
  // The band is stored in kTile x kTile node tiles; only tiles that hold band nodes are
  // allocated (a circle's band covers a fraction of its bounding box). tile_slot_ maps a
  // tile of the bounding box to its block in data_ / inner_, or -1.
  static constexpr int kTileShift = 3, kTile = 1 << kTileShift, kTileNodes = kTile * kTile;
  long node_index(int r, int c) const {  // r, c relative to (row_begin_, col_begin_), in range
    const int slot = tile_slot_[static_cast<size_t>(r >> kTileShift) * tile_cols_ + (c >> kTileShift)];
    return slot < 0 ? -1
                    : static_cast<long>(slot) * kTileNodes + ((r & (kTile - 1)) << kTileShift) + (c & (kTile - 1));
  }
  int col_begin_ = 0, row_begin_ = 0, cols_ = 0, rows_ = 0;  // bounding box of the band [px]
  int tile_cols_ = 0, tile_rows_ = 0;
  std::vector<int> tile_slot_;
  std::vector<float> data_;     // interleaved (du, dv) per stored node, float to halve memory
  std::vector<uint8_t> inner_;  // per stored node: its bicubic stencil lies in the band
  std::vector<Eigen::Vector2d> points_, normals_;
  double tangent_reach_px_ = 3.0;
  // Edge points bucketed in kSearchCell-px cells over the grid (CSR: the points of cell k
  // are search_index_[search_start_[k] .. search_start_[k + 1])), so that nearest_edge
  // searches rings of cells outward instead of scanning every point.
  static constexpr int kSearchCell = 16;
  int search_cols_ = 0, search_rows_ = 0;
  std::vector<int> search_start_, search_index_;
};

namespace detail {

// Catmull-Rom weights of the four samples at -1, 0, 1, 2 for 0 <= x < 1, and their
// derivatives: the cubic Hermite spline of ceres::CubicHermiteSpline (tangents
// (p[k+1] - p[k-1]) / 2) written as weights so that both axes share them.
inline void catmull_rom_weights(double x, double w[4], double dw[4]) {
  const double x2 = x * x, x3 = x2 * x;
  w[0] = 0.5 * (-x3 + 2.0 * x2 - x);
  w[1] = 0.5 * (3.0 * x3 - 5.0 * x2 + 2.0);
  w[2] = 0.5 * (-3.0 * x3 + 4.0 * x2 + x);
  w[3] = 0.5 * (x3 - x2);
  dw[0] = 0.5 * (-3.0 * x2 + 4.0 * x - 1.0);
  dw[1] = 0.5 * (9.0 * x2 - 10.0 * x);
  dw[2] = 0.5 * (-9.0 * x2 + 8.0 * x + 1.0);
  dw[3] = 0.5 * (3.0 * x2 - 2.0 * x);
}

}  // namespace detail

// In the header, so that the polish's pass (once per point) can inline it.
inline void EdgeDistanceField::interpolate(double u, double v, double f[2], double df_du[2],
                                           double df_dv[2]) const {
  // floor() without the libm call (no SSE4.1 in the baseline ISA); u, v are in the band.
  const auto floor_of = [](double a) {
    const int i = static_cast<int>(a);
    return static_cast<double>(a < i ? i - 1 : i);
  };
  const double u0 = floor_of(u), v0 = floor_of(v);
  const int c = static_cast<int>(u0) - col_begin_, r = static_cast<int>(v0) - row_begin_;
  double wu[4], dwu[4], wv[4], dwv[4];
  detail::catmull_rom_weights(u - u0, wu, dwu);
  detail::catmull_rom_weights(v - v0, wv, dwv);
  // The 16 nodes, interleaved (du, dv). A stencil row lies in one tile when its four
  // columns do (5 of 8 positions): one tile lookup and 8 contiguous floats.
  float node[4][8];
  const bool inside = r >= 1 && c >= 1 && r + 2 < rows_ && c + 2 < cols_;
  for (int i = 0; i < 4; ++i) {
    const int rr = r - 1 + i;
    if (inside && ((c - 1) >> kTileShift) == ((c + 2) >> kTileShift)) {
      const long idx = node_index(rr, c - 1);
      if (idx >= 0) {
        std::copy_n(data_.data() + 2 * idx, 8, node[i]);
        continue;
      }
    }
    for (int j = 0; j < 4; ++j) {
      if (inside) {
        const long idx = node_index(rr, c - 1 + j);
        node[i][2 * j] = idx >= 0 ? data_[2 * idx] : 0.0f;
        node[i][2 * j + 1] = idx >= 0 ? data_[2 * idx + 1] : 0.0f;
        continue;
      }
      double value[2];
      node_value(static_cast<int>(v0) - 1 + i, static_cast<int>(u0) - 1 + j, value);
      node[i][2 * j] = static_cast<float>(value[0]);
      node[i][2 * j + 1] = static_cast<float>(value[1]);
    }
  }
  // Both components at once (packed doubles).
  Eigen::Array2d value = Eigen::Array2d::Zero(), d_u = value, d_v = value;
  for (int i = 0; i < 4; ++i) {
    // Along the row first (value and d/du), then across the rows, as the ceres interpolator.
    Eigen::Array2d row_value = Eigen::Array2d::Zero(), row_du = row_value;
    for (int j = 0; j < 4; ++j) {
      const Eigen::Array2d p(node[i][2 * j], node[i][2 * j + 1]);
      row_value += wu[j] * p;
      row_du += dwu[j] * p;
    }
    value += wv[i] * row_value;
    d_u += wv[i] * row_du;
    d_v += dwv[i] * row_value;
  }
  for (int k = 0; k < 2; ++k) {
    f[k] = value[k];
    if (df_du != nullptr) df_du[k] = d_u[k];
    if (df_dv != nullptr) df_dv[k] = d_v[k];
  }
}

}  // namespace rgbdt::extrinsics
