#pragma once
/// \file
/// NearestKept, for rgbdt_map's registration (robust_gicp.cpp, trajectory_curve.cpp) and its test:
/// not installed.
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace rgbdt::rgbdt_map::detail {

/// A query's nearest neighbour among points that move a little between searches, found
/// again without a search while that provably gives the same answer. A search keeps the
/// kCandidates nearest, the farthest at distance dk. Later, with the query moved by m_q
/// and every target by at most m_t since, any other point is at least dk - m_q - m_t
/// away, and the candidates' own distances are measured anew: while the nearest candidate
/// is nearer than that, it is the nearest of all. A Gauss-Newton step moves points by
/// millimetres and neighbours are a voxel apart, so after the first step few points
/// search. The correspondences are those a search every step finds (but for float
/// rounding in a tie). Keeping only the runner-up (d1 + 2 (m_q + m_t) < d2) re-searched
/// twice as often on the sim street: in a merged map the runner-up is often as near.
struct NearestKept {
  static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  static constexpr int kCandidates = 4;
  std::array<std::size_t, kCandidates> candidates{};
  int count = 0;    ///< candidates found
  float dk = 0.0f;  ///< the farthest candidate's distance when searched; infinite if fewer were found
  Eigen::Vector3f at = Eigen::Vector3f::Zero();  ///< the query when searched
  float targets_moved = 0.0f;  ///< the bound on the targets' move, when searched
  bool searched = false;

  /// targets_moved_now: a bound on how far any target point moved since a fixed start;
  /// search(query, index, distance2, k) finds the k nearest; position(index) is a target
  /// point as it is now.
  template <typename Search, typename Position>
  std::size_t nearest(const pcl::PointXYZ& query, float targets_moved_now, Search&& search, Position&& position) {
    // A structure that holds the targets as they are now is never stale.
    return nearest_in_stale(query, targets_moved_now, search, position, targets_moved_now);
  }

  static constexpr std::size_t kStale = kNone - 1;
  /// As nearest, but `search` looks in a structure (a search tree) that holds the targets
  /// as they were when their move bound was `built_moved` (read after `search` ran: it may
  /// build the structure): its distances are to those places. The candidates' distances
  /// are measured anew, and any other point is at least dk - (targets_moved_now -
  /// built_moved) from the query now; when that does not tell the nearest, kStale: build
  /// the structure anew and ask again. The answer is the one a fresh search would give.
  template <typename Search, typename Position>
  std::size_t nearest_in_stale(const pcl::PointXYZ& query, float targets_moved_now, Search&& search,
                               Position&& position, const float& built_moved) {
    const Eigen::Vector3f q = query.getVector3fMap();
    if (searched) {
      const std::size_t kept = proven(q, targets_moved_now, position);
      if (kept != kUnproven) return kept;
    }
    searched_now(query, search);
    targets_moved = built_moved;
    if (built_moved == targets_moved_now) return count >= 1 ? candidates[0] : kNone;
    const std::size_t found = proven(q, targets_moved_now, position);
    return found != kUnproven ? found : kStale;
  }

 private:
  static constexpr std::size_t kUnproven = kNone - 2;

  /// The nearest candidate by the targets' places now, when the bound proves it the nearest
  /// of all targets; kUnproven otherwise.
  template <typename Position>
  std::size_t proven(const Eigen::Vector3f& q, float targets_moved_now, Position&& position) const {
    const float others_at_least = dk - (q - at).norm() - (targets_moved_now - targets_moved);
    std::size_t best = kNone;
    float best_distance2 = std::numeric_limits<float>::infinity();
    for (int c = 0; c < count; ++c) {
      const float d2 = (position(candidates[c]) - q).squaredNorm();
      if (d2 < best_distance2) {
        best_distance2 = d2;
        best = candidates[c];
      }
    }
    if (count == 0 || (others_at_least > 0.0f && best_distance2 < others_at_least * others_at_least)) return best;
    return kUnproven;
  }

  template <typename Search>
  void searched_now(const pcl::PointXYZ& query, Search&& search) {
    std::vector<int>& found = scratch_index();
    std::vector<float>& distance2 = scratch_distance2();
    count = search(query, found, distance2, kCandidates);
    searched = true;
    at = query.getVector3fMap();
    for (int c = 0; c < count; ++c) candidates[c] = static_cast<std::size_t>(found[c]);
    dk = count == kCandidates ? std::sqrt(distance2[kCandidates - 1]) : std::numeric_limits<float>::infinity();
  }

  static std::vector<int>& scratch_index() {
    thread_local std::vector<int> v(kCandidates);
    return v;
  }
  static std::vector<float>& scratch_distance2() {
    thread_local std::vector<float> v(kCandidates);
    return v;
  }
};

}  // namespace rgbdt::rgbdt_map::detail
