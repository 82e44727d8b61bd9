#pragma once
/// \file
/// Image headers read without decoding the image (PNG's IHDR chunk, JPEG's SOF marker), so
/// that a preflight can check every frame of a session against its camera_info before the
/// long work, and so that an image too large to decode is refused before an image library
/// allocates memory for it. No image library is used.
#include <cstdint>
#include <string>

#include "rgbdt/core/camera.hpp"

namespace rgbdt::core {

/// Largest decoded size (width x height x channels x bytes per sample); the largest width
/// and height is kMaxImageSide (camera.hpp), shared with the camera_info reader. Far above
/// any camera of a rig; a header beyond them is corrupt or hostile.
constexpr std::uint64_t kMaxImageBytes = std::uint64_t{1} << 30;

struct ImageHeader {
  int width = 0;
  int height = 0;
  /// Bits per sample as stored: PNG 1, 2, 4, 8 or 16; JPEG 8 or 12.
  int bit_depth = 0;
  /// Channels an image library decodes to: 1 grey, 2 grey + alpha, 3 colour (also
  /// palette PNGs and CMYK JPEGs), 4 colour + alpha.
  int channels = 0;
  /// "png" or "jpeg".
  std::string format;
};

/// Reads and checks the header of a PNG or JPEG file: the signature, for PNG the IHDR
/// chunk (length, CRC, bit depth valid for the colour type, compression/filter/interlace
/// methods), for JPEG the first SOF marker; width and height in 1..kMaxImageSide and the
/// decoded size within kMaxImageBytes. Reads at most the header bytes (JPEG: the markers
/// before SOF, bounded by the file size). Throws rgbdt::core::Error naming the file, the
/// value and what was expected.
ImageHeader read_image_header(const std::string& path);

/// What is wrong with an image against what its camera_info says, as one line naming both
/// files ("" when it matches): width and height must equal expected_width x
/// expected_height; expected_bit_depth, when not 0, must equal the bit depth (8 for RGB,
/// 16 for raw thermal counts), and when 0 the bit depth must be 8 or 16. For a preflight
/// that lists every problem at once.
std::string image_mismatch(const ImageHeader& header, int expected_width, int expected_height,
                           const std::string& path, const std::string& camera_info_path,
                           int expected_bit_depth = 0);

/// Throws rgbdt::core::Error naming `path` with image_mismatch()'s message when it is not
/// empty.
void check_image_matches(const ImageHeader& header, int expected_width, int expected_height,
                         const std::string& path, const std::string& camera_info_path,
                         int expected_bit_depth = 0);

}  // namespace rgbdt::core
