#pragma once
// Decoded ROS messages into the files of the session contracts: images as cv::Mat for PNG,
// clouds as the PCD of design.md (x y z, and intensity, ring, t when the cloud has them),
// CameraInfo as camera_info intrinsics.
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/core/camera.hpp"

namespace rgbdt::import {

/// True for the Image encodings image_to_mat converts: mono8, 8UC1, mono16, 16UC1, rgb8,
/// bgr8, rgba8, bgra8, bayer_{rggb,bggr,gbrg,grbg}8.
bool is_supported_encoding(const std::string& encoding);

/// The image as PNG-ready pixels: 8-bit grey, 16-bit grey (counts kept as stored) or 8-bit
/// BGR (OpenCV's order; the PNG holds RGB). Bayer images are demosaiced. Throws core::Error
/// naming the message (context) for an unsupported encoding, a step smaller than a row or
/// data shorter than height * step.
cv::Mat image_to_mat(const bag::Image& image, const bag::MessageContext& context);

/// A CompressedImage (format "jpeg", "png" or "<encoding>; jpeg compressed <encoding>")
/// decoded with cv::imdecode, bit depth kept. Throws core::Error naming the message for a
/// format that is not jpeg or png (e.g. compressedDepth) or bytes that do not decode.
cv::Mat compressed_to_mat(const bag::CompressedImage& image, const bag::MessageContext& context);

/// One cloud ready for a PCD: the returns only (finite, not at the origin), channels as in
/// CloudPoints.
struct PcdCloud {
  std::vector<float> xyz;           ///< x y z per point [m]
  std::vector<float> intensity;     ///< empty when the cloud has none
  std::vector<std::uint16_t> ring;  ///< empty when the cloud has none
  std::vector<float> t;             ///< [s] from first_time_ns; empty when no per-point time
  std::int64_t first_time_ns = 0;   ///< earliest point time, or the header stamp without times
  std::size_t size() const { return xyz.size() / 3; }
};

/// The returns of `points`: points with a non-finite coordinate and points at exactly (0, 0, 0)
/// (the missing-return marker of Hesai and Ouster drivers) are dropped. t counts from the
/// earliest kept point's time.
/// `stamp_ns` stands for the cloud's time when it has no per-point times.
PcdCloud to_pcd_cloud(const bag::CloudPoints& points, std::int64_t stamp_ns);

/// Appends `more` to `into`, its t shifted to count from into.first_time_ns (the clouds of a
/// still interval accumulate into one). Channels one cloud lacks are dropped from the result.
void append_cloud(PcdCloud& into, const PcdCloud& more);

/// The cloud as binary PCD text (VERSION 0.7, DATA binary).
std::string format_pcd(const PcdCloud& cloud);

/// Intrinsics from a CameraInfo: K's fx fy cx cy, D with plumb_bob or equidistant. Throws
/// core::Error naming the message for another distortion model, a K without focal lengths (an
/// uncalibrated camera publishes zeros) or intrinsics that fail validate().
core::CameraIntrinsics to_intrinsics(const bag::CameraInfo& info, const std::string& camera_name,
                                     const bag::MessageContext& context);

}  // namespace rgbdt::import
