#pragma once
/// \file
/// Pairing of a view's LIDAR holes with its image ellipses by position. The LIDAR and image
/// detectors each order a multi-hole board's holes from their own viewpoint, and a LIDAR
/// mounted rolled or upside down against the camera lists them in another order, so an
/// index does not identify a hole across the two.
#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <numeric>
#include <opencv2/core/types.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace rgbdt::extrinsics {

/// For each projected LIDAR hole centre [px], the index of the image ellipse it is paired
/// with: the one-to-one assignment of least total squared distance between the points and
/// the ellipse centres (every permutation for up to 7 holes; beyond that the given order).
/// Throws std::invalid_argument when there are more points than ellipses.
inline std::vector<std::size_t> pair_holes_by_position(const std::vector<Eigen::Vector2d>& points,
                                                       const std::vector<cv::RotatedRect>& ellipses) {
  if (points.size() > ellipses.size())
    throw std::invalid_argument("pair_holes_by_position: " + std::to_string(points.size()) + " holes for " +
                                std::to_string(ellipses.size()) + " ellipses (expected at most as many)");
  std::vector<std::size_t> perm(ellipses.size());
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  std::vector<std::size_t> best(perm.begin(), perm.begin() + static_cast<std::ptrdiff_t>(points.size()));
  if (ellipses.size() > 7) return best;
  double best_cost = std::numeric_limits<double>::infinity();
  do {
    double cost = 0.0;
    for (std::size_t i = 0; i < points.size() && cost < best_cost; ++i) {
      const Eigen::Vector2d d = points[i] - Eigen::Vector2d(ellipses[perm[i]].center.x, ellipses[perm[i]].center.y);
      cost += d.squaredNorm();
    }
    if (cost < best_cost) {
      best_cost = cost;
      std::copy(perm.begin(), perm.begin() + static_cast<std::ptrdiff_t>(points.size()), best.begin());
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return best;
}

}  // namespace rgbdt::extrinsics
