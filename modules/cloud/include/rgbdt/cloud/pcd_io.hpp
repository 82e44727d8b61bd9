#pragma once
/// \file
/// Reading and writing PCD files (ASCII, binary, binary_compressed), with errors that name
/// the file and what was expected. Reading parses and checks the file here (LZF through
/// PCL's decoder, after the sizes are checked); writing goes through PCL. For PLY files and
/// for picking the reader by extension see cloud_io.hpp. Files may carry any subset of the
/// optional fields; which ones were present is reported so callers can recover the rest
/// (e.g. scan lines from geometry when `ring` is absent).
#include <pcl/PCLPointCloud2.h>

#include <string>

#include "rgbdt/cloud/point_types.hpp"

namespace rgbdt::cloud {

struct LoadedCloud {
  Cloud::Ptr cloud;
  bool has_intensity = false;
  bool has_ring = false;
  bool has_t = false;
};

/// Loads a PCD. Requires fields x y z; intensity (or "i"), ring and t (or "time",
/// "timestamp") are optional and zero when absent. Points with non-finite coordinates are
/// dropped (PCL writes NaN for missing returns in organised clouds).
///
/// The header is parsed and checked before any data is read: FIELDS/SIZE/TYPE/COUNT of one
/// length, sizes 1/2/4/8 matching the types, WIDTH x HEIGHT == POINTS, and the data size
/// the header implies present in the file (for binary_compressed: the stored sizes within
/// the file, the uncompressed size equal to POINTS x point size and at most 88 times the
/// compressed size, LZF's largest expansion). Values are checked too: `t` finite and within
/// 3600 s of the earliest point (absolute "time"/"timestamp" fields are made relative
/// first), `ring` a whole number in 0..kMaxRing, intensity finite.
///
/// Throws rgbdt::core::Error naming the file, and the point or header value at fault, when
/// it is missing, unreadable, malformed, truncated or lacks x y z.
LoadedCloud load_pcd(const std::string& path);

/// Loads a PCD of any point type for pcl::fromPCLPointCloud2: the same header, size and
/// compressed-size checks as load_pcd run before any data is decoded, then the body is
/// handed over as PCL's blob (fields at their offsets, one unorganised row; no value
/// checks, no fields required). Throws rgbdt::core::Error naming the file as load_pcd does.
pcl::PCLPointCloud2 load_pcd_blob(const std::string& path);

enum class PcdFormat { kAscii, kBinary, kBinaryCompressed };

/// Writes all fields of the cloud. Throws rgbdt::core::Error naming the file on failure.
void save_pcd(const std::string& path, const Cloud& cloud, PcdFormat format = PcdFormat::kBinary);

}  // namespace rgbdt::cloud
