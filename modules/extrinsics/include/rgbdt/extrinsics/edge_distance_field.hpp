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
/// biased by up to ~0.15 px towards the grid nodes). The grid covers the edges' bounding
/// box plus a margin; beyond it the field is continued by the offset to the grid border,
/// so points projected far outside the image still feel a gradient.
#include <Eigen/Core>
#include <string>
#include <vector>

namespace rgbdt::extrinsics {

struct EdgeFieldOptions {
  /// Grid margin around the edges' bounding box [px]. Larger margins give the exact
  /// field further from the target (helps large initial offsets) at more memory/time.
  double margin_px = 200.0;
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

  /// Bicubic-interpolated offset vector at a pixel (continued outside the grid).
  Eigen::Vector2d offset(const Eigen::Vector2d& px) const;
  double distance_px(const Eigen::Vector2d& px) const { return offset(px).norm(); }

 private:
  int col_begin_ = 0, row_begin_ = 0, cols_ = 0, rows_ = 0;
  std::vector<float> data_;
};

}  // namespace rgbdt::extrinsics
