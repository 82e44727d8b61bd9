#pragma once
/// \file
/// PointTree, for rgbdt_map's registration (robust_gicp.cpp, trajectory_curve.cpp, odometry.cpp)
/// and its test: not installed.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <memory>
#include <nanoflann.hpp>
#include <vector>

namespace rgbdt::rgbdt_map::detail {

/// The exact k nearest neighbours among the points of a cloud of finite points: nanoflann's
/// k-d tree over the points where they lie, leaves of up to 16 points. It answers as PCL's
/// KdTreeFLANN (the calls used here have its names) but for the order of points at equal
/// distances, and costs less: FLANN copies the cloud into an array of its own to build, and
/// PCL's wrapper allocates on every search. On a 0.25 m merged map of 20 sim street tilts
/// (61k points, 5k queries), leaves of 16 took 0.7x FLANN's time to find 4 neighbours,
/// 0.9x to find 20, and 0.9x to build (leaves of 10 or 24: within 1.5 % of 16's instructions
/// in `--accurate` Odometry). Odometry's instructions over seed 1's first 40 tilts
/// (`--accurate`, callgrind): 0.82x. rgbdt_map_bench prints both trees on its merged map.
class PointTree {
 public:
  using Cloud = pcl::PointCloud<pcl::PointXYZ>;

  PointTree() = default;
  PointTree(const PointTree&) = delete;  // the index refers to adaptor_
  PointTree& operator=(const PointTree&) = delete;

  void setInputCloud(Cloud::ConstPtr cloud) {
    index_.reset();
    cloud_ = std::move(cloud);
    adaptor_.cloud = cloud_.get();
    index_ = std::make_unique<Index>(3, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafPoints));
  }

  /// The k nearest points (fewer when the cloud has fewer) into index and distance2,
  /// nearest first; returns how many.
  int nearestKSearch(const pcl::PointXYZ& query, int k, std::vector<int>& index, std::vector<float>& distance2) const {
    if (!index_ || k <= 0) return 0;
    const auto wanted = static_cast<std::size_t>(k);
    if (index.size() < wanted) index.resize(wanted);
    if (distance2.size() < wanted) distance2.resize(wanted);
    nanoflann::KNNResultSet<float, int, std::size_t> found(wanted);
    found.init(index.data(), distance2.data());
    index_->findNeighbors(found, query.data, nanoflann::SearchParams());
    return static_cast<int>(found.size());
  }

 private:
  static constexpr std::size_t kLeafPoints = 16;

  /// nanoflann's view of the cloud.
  struct Adaptor {
    const Cloud* cloud = nullptr;
    std::size_t kdtree_get_point_count() const { return cloud->size(); }
    float kdtree_get_pt(std::size_t i, std::size_t dimension) const { return (*cloud)[i].data[dimension]; }
    template <typename Box>
    bool kdtree_get_bbox(Box&) const {
      return false;  // nanoflann computes it
    }
  };
  using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>, Adaptor, 3, int>;

  Cloud::ConstPtr cloud_;
  Adaptor adaptor_;
  std::unique_ptr<Index> index_;
};

}  // namespace rgbdt::rgbdt_map::detail
