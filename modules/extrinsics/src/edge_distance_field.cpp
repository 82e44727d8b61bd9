#include "rgbdt/extrinsics/edge_distance_field.hpp"

#include <ceres/cubic_interpolation.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace rgbdt::extrinsics {

std::string EdgeFieldOptions::validate() const {
  std::ostringstream os;
  if (!(margin_px >= 2.0)) os << "margin_px = " << margin_px << ", expected >= 2; ";
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
  col_begin_ = static_cast<int>(std::floor(lo.x() - options.margin_px));
  row_begin_ = static_cast<int>(std::floor(lo.y() - options.margin_px));
  cols_ = static_cast<int>(std::ceil(hi.x() + options.margin_px)) - col_begin_ + 1;
  rows_ = static_cast<int>(std::ceil(hi.y() + options.margin_px)) - row_begin_ + 1;
  if (static_cast<long>(cols_) * rows_ > options.max_nodes) {
    std::ostringstream os;
    os << "EdgeDistanceField: edge points span " << cols_ << " x " << rows_
       << " px with the margin, more than max_nodes = " << options.max_nodes
       << " (stray edge points far from the target?)";
    throw std::invalid_argument(os.str());
  }
  const int n = static_cast<int>(edge_points_px.size());

  // Bucket the points by their nearest grid pixel (linked lists over the grid).
  std::vector<int> head(static_cast<size_t>(cols_) * rows_, -1), next(n, -1);
  cv::Mat seeds(rows_, cols_, CV_8U, cv::Scalar(255));
  for (int i = 0; i < n; ++i) {
    const int c = static_cast<int>(std::lround(edge_points_px[i].x())) - col_begin_;
    const int r = static_cast<int>(std::lround(edge_points_px[i].y())) - row_begin_;
    const size_t idx = static_cast<size_t>(r) * cols_ + c;
    next[i] = head[idx];
    head[idx] = i;
    seeds.at<uint8_t>(r, c) = 0;
  }
  auto for_points_near = [&](int c0, int r0, int reach, auto&& fn) {
    for (int r = std::max(0, r0 - reach); r <= std::min(rows_ - 1, r0 + reach); ++r) {
      for (int c = std::max(0, c0 - reach); c <= std::min(cols_ - 1, c0 + reach); ++c) {
        for (int i = head[static_cast<size_t>(r) * cols_ + c]; i >= 0; i = next[i]) fn(i);
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

  // Nearest seed pixel of every node (Voronoi labels of the distance transform), then the
  // nearest sub-pixel point among the seeds around it.
  cv::Mat dist, labels;
  cv::distanceTransform(seeds, dist, labels, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<Eigen::Vector2i> label_pixel(static_cast<size_t>(n) + 2, Eigen::Vector2i(-1, -1));
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      if (seeds.at<uint8_t>(r, c) == 0) {
        const int label = labels.at<int>(r, c);
        if (label >= static_cast<int>(label_pixel.size())) label_pixel.resize(label + 1, {-1, -1});
        label_pixel[label] = {c, r};
      }
    }
  }
  data_.assign(static_cast<size_t>(cols_) * rows_ * 2, 0.0f);
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      const Eigen::Vector2d x(c + col_begin_, r + row_begin_);
      const int label = labels.at<int>(r, c);
      const Eigen::Vector2i seed = label_pixel[label];
      int best = -1;
      double best_d2 = std::numeric_limits<double>::infinity();
      for_points_near(seed.x(), seed.y(), 2, [&](int j) {
        const double d2 = (x - edge_points_px[j]).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best = j;
        }
      });
      Eigen::Vector2d offset = x - edge_points_px[best];
      const Eigen::Vector2d& nrm = normals[best];
      if (nrm.squaredNorm() > 0.5) {
        // Tangent-line distance, except beyond the end of an open edge where the tangent
        // line would continue the edge into empty space.
        const Eigen::Vector2d tangent(-nrm.y(), nrm.x());
        if (std::abs(offset.dot(tangent)) <= options.normal_radius_px) {
          offset = offset.dot(nrm) * nrm;
        }
      }
      const size_t idx = (static_cast<size_t>(r) * cols_ + c) * 2;
      data_[idx] = static_cast<float>(offset.x());
      data_[idx + 1] = static_cast<float>(offset.y());
    }
  }
}

Eigen::Vector2d EdgeDistanceField::offset(const Eigen::Vector2d& px) const {
  const ceres::Grid2D<float, 2> grid(data_.data(), row_begin_, row_begin_ + rows_, col_begin_,
                                     col_begin_ + cols_);
  const ceres::BiCubicInterpolator<ceres::Grid2D<float, 2>> interpolator(grid);
  const double u = std::clamp(px.x(), double(col_begin_), double(col_begin_ + cols_ - 1));
  const double v = std::clamp(px.y(), double(row_begin_), double(row_begin_ + rows_ - 1));
  double f[2];
  interpolator.Evaluate(v, u, f);
  return {f[0] + (px.x() - u), f[1] + (px.y() - v)};
}

}  // namespace rgbdt::extrinsics
