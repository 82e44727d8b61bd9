#include "rgbdt/core/image_header.hpp"

#include <array>
#include <filesystem>
#include <fstream>
#include <vector>

#include "rgbdt/core/error.hpp"

namespace rgbdt::core {
namespace {

std::uint32_t be32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) << 24 | static_cast<std::uint32_t>(p[1]) << 16 |
         static_cast<std::uint32_t>(p[2]) << 8 | static_cast<std::uint32_t>(p[3]);
}

unsigned be16(const unsigned char* p) { return static_cast<unsigned>(p[0]) << 8 | p[1]; }

std::uint32_t crc32(const unsigned char* data, std::size_t n) {
  std::uint32_t c = 0xffffffffu;
  for (std::size_t i = 0; i < n; ++i) {
    c ^= data[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return c ^ 0xffffffffu;
}

// Reads up to n bytes at `offset`; returns how many were read.
std::size_t read_at(std::ifstream& in, std::uint64_t offset, unsigned char* out, std::size_t n) {
  in.clear();
  in.seekg(static_cast<std::streamoff>(offset));
  in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
  return static_cast<std::size_t>(in.gcount());
}

std::string hex(unsigned byte) {
  static const char* digits = "0123456789ABCDEF";
  return std::string("0x") + digits[(byte >> 4) & 15] + digits[byte & 15];
}

std::string label(const ImageHeader& h) { return h.format == "png" ? "PNG" : "JPEG"; }

// Sets h.width/height from the header's values after checking them against the caps.
void check_size(ImageHeader& h, std::uint64_t width, std::uint64_t height,
                const std::string& path) {
  if (width == 0 || height == 0 || width > static_cast<std::uint64_t>(kMaxImageSide) ||
      height > static_cast<std::uint64_t>(kMaxImageSide)) {
    throw Error(path, label(h) + " header says " + std::to_string(width) + "x" +
                          std::to_string(height) + " pixels, expected width and height in 1.." +
                          std::to_string(kMaxImageSide));
  }
  h.width = static_cast<int>(width);
  h.height = static_cast<int>(height);
  const std::uint64_t bytes = static_cast<std::uint64_t>(h.width) *
                              static_cast<std::uint64_t>(h.height) *
                              static_cast<std::uint64_t>(h.channels) * (h.bit_depth > 8 ? 2u : 1u);
  if (bytes > kMaxImageBytes) {
    throw Error(path, label(h) + " header says " + std::to_string(h.width) + "x" +
                          std::to_string(h.height) + " pixels x " + std::to_string(h.channels) +
                          " channels = " + std::to_string(bytes) +
                          " bytes decoded, expected at most " + std::to_string(kMaxImageBytes));
  }
}

ImageHeader read_png(std::ifstream& in, const std::string& path) {
  // Signature (8), IHDR length (4) and type (4), IHDR data (13), CRC (4).
  std::array<unsigned char, 33> b{};
  const std::size_t got = read_at(in, 0, b.data(), b.size());
  if (got < b.size()) {
    throw Error(path, "PNG ends after " + std::to_string(got) +
                          " bytes, expected at least 33 (signature and IHDR)");
  }
  if (be32(&b[8]) != 13 || std::string(reinterpret_cast<const char*>(&b[12]), 4) != "IHDR") {
    throw Error(path, "PNG's first chunk is not a 13-byte IHDR (corrupt or truncated file)");
  }
  ImageHeader h;
  h.format = "png";
  h.bit_depth = b[24];
  const int colour = b[25];
  bool depth_ok = false;
  switch (colour) {
    case 0:
      h.channels = 1;
      depth_ok = h.bit_depth == 1 || h.bit_depth == 2 || h.bit_depth == 4 || h.bit_depth == 8 ||
                 h.bit_depth == 16;
      break;
    case 2:
      h.channels = 3;
      depth_ok = h.bit_depth == 8 || h.bit_depth == 16;
      break;
    case 3:
      h.channels = 3;
      depth_ok = h.bit_depth == 1 || h.bit_depth == 2 || h.bit_depth == 4 || h.bit_depth == 8;
      break;
    case 4:
      h.channels = 2;
      depth_ok = h.bit_depth == 8 || h.bit_depth == 16;
      break;
    case 6:
      h.channels = 4;
      depth_ok = h.bit_depth == 8 || h.bit_depth == 16;
      break;
    default:
      throw Error(path, "PNG colour type " + std::to_string(colour) + ", expected 0, 2, 3, 4 or 6");
  }
  if (!depth_ok) {
    throw Error(path, "PNG bit depth " + std::to_string(h.bit_depth) +
                          " is not valid for colour type " + std::to_string(colour));
  }
  if (b[26] != 0 || b[27] != 0 || b[28] > 1) {
    throw Error(path, "PNG compression/filter/interlace methods " + std::to_string(b[26]) + "/" +
                          std::to_string(b[27]) + "/" + std::to_string(b[28]) +
                          ", expected 0/0/0 or 0/0/1");
  }
  // The size is checked before the CRC, so that an oversized claim is reported as such
  // whatever its checksum.
  check_size(h, be32(&b[16]), be32(&b[20]), path);
  if (crc32(&b[12], 17) != be32(&b[29])) {
    throw Error(path, "PNG IHDR chunk fails its CRC check (corrupt file)");
  }
  return h;
}

ImageHeader read_jpeg(std::ifstream& in, std::uint64_t file_size, const std::string& path) {
  std::uint64_t pos = 2;  // after SOI
  unsigned char b[8];
  while (true) {
    // A marker: one or more 0xFF, then the code.
    if (read_at(in, pos, b, 1) != 1) break;
    if (b[0] != 0xff) {
      throw Error(path, "JPEG has byte " + hex(b[0]) + " at offset " + std::to_string(pos) +
                            " where a marker (0xFF..) was expected (corrupt file)");
    }
    unsigned marker = 0xff;
    while (marker == 0xff) {
      ++pos;
      if (read_at(in, pos, b, 1) != 1) break;
      marker = b[0];
    }
    if (marker == 0xff) break;
    ++pos;
    if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd8)) continue;  // no length
    if (marker == 0xd9 || marker == 0xda) {
      throw Error(path,
                  "JPEG reaches its image data without a SOF marker (no width/height), expected a "
                  "baseline or progressive JPEG");
    }
    if (read_at(in, pos, b, 2) != 2) break;
    const unsigned length = be16(b);
    if (length < 2 || pos + length > file_size) {
      throw Error(path, "JPEG segment 0xFF" + hex(marker).substr(2) + " at offset " +
                            std::to_string(pos) + " has length " + std::to_string(length) +
                            ", expected 2.." + std::to_string(file_size - pos) +
                            " (corrupt or truncated file)");
    }
    const bool sof =
        marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (sof) {
      if (length < 8 || read_at(in, pos + 2, b, 6) != 6) {
        throw Error(
            path, "JPEG SOF segment of length " + std::to_string(length) + ", expected at least 8");
      }
      ImageHeader h;
      h.format = "jpeg";
      h.bit_depth = b[0];
      const int components = b[5];
      if (h.bit_depth != 8 && h.bit_depth != 12) {
        throw Error(path,
                    "JPEG sample precision " + std::to_string(h.bit_depth) + ", expected 8 or 12");
      }
      if (components != 1 && components != 3 && components != 4) {
        throw Error(path,
                    "JPEG has " + std::to_string(components) + " components, expected 1, 3 or 4");
      }
      h.channels = components == 1 ? 1 : 3;
      check_size(h, be16(&b[3]), be16(&b[1]), path);
      return h;
    }
    pos += length;
  }
  throw Error(path, "JPEG ends at offset " + std::to_string(pos) +
                        " without a SOF marker (truncated file)");
}

}  // namespace

ImageHeader read_image_header(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) throw Error(path, "image file does not exist");
  if (!fs::is_regular_file(status))
    throw Error(path, "is not a regular file, expected a PNG or JPEG image");
  const std::uint64_t size = fs::file_size(path, ec);
  if (ec) throw Error(path, "cannot read the size of the image file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path, "cannot open image file for reading");
  if (size == 0) throw Error(path, "image file is empty (0 bytes), expected a PNG or JPEG");
  unsigned char sig[8] = {};
  const std::size_t got = read_at(in, 0, sig, sizeof sig);
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (got == 8 && std::equal(sig, sig + 8, kPng)) return read_png(in, path);
  if (got >= 3 && sig[0] == 0xff && sig[1] == 0xd8 && sig[2] == 0xff)
    return read_jpeg(in, size, path);
  throw Error(path, "is neither a PNG nor a JPEG (no PNG signature, no JPEG start marker)");
}

std::string image_mismatch(const ImageHeader& header, int expected_width, int expected_height,
                           const std::string& path, const std::string& camera_info_path,
                           int expected_bit_depth) {
  std::string problems;
  const auto add = [&](const std::string& p) { problems += (problems.empty() ? "" : "; ") + p; };
  if (header.width != expected_width || header.height != expected_height) {
    add("image is " + std::to_string(header.width) + "x" + std::to_string(header.height) + ", " +
        camera_info_path + " says " + std::to_string(expected_width) + "x" +
        std::to_string(expected_height) + " (image_width x image_height)");
  }
  if (expected_bit_depth != 0 && header.bit_depth != expected_bit_depth) {
    add("image has " + std::to_string(header.bit_depth) + "-bit samples, expected " +
        std::to_string(expected_bit_depth) + "-bit for the camera of " + camera_info_path);
  } else if (expected_bit_depth == 0 && header.bit_depth != 8 && header.bit_depth != 16) {
    add("image has " + std::to_string(header.bit_depth) + "-bit samples, expected 8 or 16");
  }
  return problems.empty() ? problems : path + ": " + problems;
}

void check_image_matches(const ImageHeader& header, int expected_width, int expected_height,
                         const std::string& path, const std::string& camera_info_path,
                         int expected_bit_depth) {
  std::string message = image_mismatch(header, expected_width, expected_height, path,
                                       camera_info_path, expected_bit_depth);
  if (message.empty()) return;
  // Error(path, ...) prefixes the path itself.
  throw Error(path, message.substr(path.size() + 2));
}

}  // namespace rgbdt::core
