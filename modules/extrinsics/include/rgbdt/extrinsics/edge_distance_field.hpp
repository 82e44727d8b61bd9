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
/// band around the edges (cheap to build); outside the band the same quantity is computed
/// exactly from the nearest edge point (brute force), so points projected far from the
/// target, even outside the image, still feel the true distance and its gradient.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace rgbdt::extrinsics {

struct EdgeFieldOptions {
  /// Half-width of the interpolated band around the edges [px]. Points beyond it use the
  /// exact nearest-point form (slower per evaluation, same values), so this only trades
  /// build time against evaluation time; raise it when residuals stay large (noisy edges).
  double band_px = 6.0;
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

  int col_begin() const { return col_begin_; }  ///< u of the first grid column [px]
  int row_begin() const { return row_begin_; }  ///< v of the first grid row [px]
  int cols() const { return cols_; }
  int rows() const { return rows_; }
  /// Interleaved (du, dv) per node, row-major, float to halve memory.
  const std::vector<float>& data() const { return data_; }

  /// True when the bicubic stencil at the pixel lies in the filled band.
  bool in_band(double u, double v) const {
    const long c = std::lround(u) - col_begin_, r = std::lround(v) - row_begin_;
    return c >= 0 && r >= 0 && c < cols_ && r < rows_ && inner_[static_cast<size_t>(r) * cols_ + c];
  }
  /// The offset vector at a pixel: bicubic inside the band, exact outside.
  Eigen::Vector2d offset(const Eigen::Vector2d& px) const;
  /// Exact form at any pixel: the nearest edge point and its unit normal; the normal is
  /// zero where the point-to-point offset applies (isolated points, beyond an edge's end).
  /// offset = ((px - point) . normal) normal, or px - point when the normal is zero.
  void nearest_edge(const Eigen::Vector2d& px, Eigen::Vector2d* point,
                    Eigen::Vector2d* normal) const;
  double distance_px(const Eigen::Vector2d& px) const { return offset(px).norm(); }

 private:
  int col_begin_ = 0, row_begin_ = 0, cols_ = 0, rows_ = 0;
  std::vector<float> data_;
  std::vector<uint8_t> inner_;
  std::vector<Eigen::Vector2d> points_, normals_;
  double tangent_reach_px_ = 3.0;
  // Edge points bucketed in kSearchCell-px cells over the grid (CSR: the points of cell k
  // are search_index_[search_start_[k] .. search_start_[k + 1])), so that nearest_edge
  // searches rings of cells outward instead of scanning every point.
  static constexpr int kSearchCell = 16;
  int search_cols_ = 0, search_rows_ = 0;
  std::vector<int> search_start_, search_index_;
};

}  // namespace rgbdt::extrinsics
