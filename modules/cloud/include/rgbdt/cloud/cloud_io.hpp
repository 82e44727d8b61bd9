#pragma once
/// \file
/// Reading point clouds from PCD or PLY files into the same LoadedCloud. Every reader
/// checks the header against the file's size before it allocates anything from a header
/// value, and checks the values it returns: a broken, truncated or hostile file ends in
/// rgbdt::core::Error naming the file, the value and what was expected, never in a crash
/// or in silently wrong points.
#include <string>

#include "rgbdt/cloud/pcd_io.hpp"

namespace rgbdt::cloud {

/// Loads a PLY (format ascii 1.0, binary_little_endian 1.0 or binary_big_endian 1.0, as
/// CloudCompare, PCL and Open3D write them). Reads the `vertex` element: properties x y z
/// are required; intensity (also "scalar_intensity", "i", "reflectivity"), ring ("line",
/// "laser_id") and t ("time", "timestamp") are optional, matched without regard to case and
/// to CloudCompare's "scalar_" prefix. Other elements (faces) are ignored. Same value checks
/// as load_pcd.
LoadedCloud load_ply(const std::string& path);

/// load_pcd or load_ply by the file's extension (.pcd or .ply, any case); any other
/// extension is an error naming the file.
LoadedCloud load_cloud(const std::string& path);

}  // namespace rgbdt::cloud
