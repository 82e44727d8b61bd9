#pragma once
/// \file
/// The point type of rgbdt clouds, as stored in PCD files (design.md):
///   x y z      [m], LIDAR frame
///   intensity  LIDAR return intensity (device units)
///   ring       scan-line index (for a tilting 2D LIDAR: the scan number within the tilt)
///   t          [s] from the cloud's first point
#define PCL_NO_PRECOMPILE
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstdint>

namespace rgbdt::cloud {

/// The largest scan-line index a cloud may carry. Spinning LIDARs have at most 128 rings; an
/// assembled tilt has one ring per 2D scan, so 16383 covers a single tilt of 6.8 minutes at
/// 40 scans/s. Larger values (65535 is the "no ring" sentinel of some drivers) are corrupt.
constexpr int kMaxRing = 16383;

struct EIGEN_ALIGN16 PointXYZIRT {
  PCL_ADD_POINT4D;
  float intensity = 0.0f;
  std::uint16_t ring = 0;
  float t = 0.0f;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

using Cloud = pcl::PointCloud<PointXYZIRT>;

}  // namespace rgbdt::cloud

POINT_CLOUD_REGISTER_POINT_STRUCT(rgbdt::cloud::PointXYZIRT,
                                  (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)(
                                      std::uint16_t, ring, ring)(float, t, t))
