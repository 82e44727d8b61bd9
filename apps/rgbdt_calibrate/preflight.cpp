#include "preflight.hpp"

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <system_error>

namespace rgbdt::calibrate {

namespace fs = std::filesystem;

namespace {

/// Why `path` cannot serve as an input file, or an empty string.
std::string file_problem(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) return "does not exist";
  if (!fs::is_regular_file(st)) return "is not a regular file";
  const auto size = fs::file_size(path, ec);
  if (ec) return "cannot read its size (" + ec.message() + ")";
  if (size == 0) return "is empty (0 bytes)";
  std::ifstream f(path, std::ios::binary);
  char c;
  if (!f || !f.get(c)) return "cannot be read";
  return {};
}

}  // namespace

bool read_png_size(const std::string& path, int* width, int* height, std::string* why) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    *why = "cannot be read";
    return false;
  }
  std::array<unsigned char, 24> h{};
  f.read(reinterpret_cast<char*>(h.data()), static_cast<std::streamsize>(h.size()));
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (f.gcount() < 8 || !std::equal(kSignature, kSignature + 8, h.begin())) {
    *why = "is not a PNG (no PNG signature in its first 8 bytes)";
    return false;
  }
  if (f.gcount() < 24 || h[12] != 'I' || h[13] != 'H' || h[14] != 'D' || h[15] != 'R') {
    *why = "is a truncated PNG (no IHDR chunk at byte 12)";
    return false;
  }
  const auto be32 = [&](int at) {
    return (static_cast<unsigned long>(h[at]) << 24) | (static_cast<unsigned long>(h[at + 1]) << 16) |
           (static_cast<unsigned long>(h[at + 2]) << 8) | static_cast<unsigned long>(h[at + 3]);
  };
  const unsigned long w = be32(16), ht = be32(20);
  if (w == 0 || ht == 0 || w > 0x7fffffffUL || ht > 0x7fffffffUL) {
    *why = "has an invalid IHDR size " + std::to_string(w) + "x" + std::to_string(ht);
    return false;
  }
  *width = static_cast<int>(w);
  *height = static_cast<int>(ht);
  return true;
}

std::vector<std::string> preflight_problems(const core::CalibrationSession& session,
                                            const std::map<std::string, core::CameraIntrinsics>& intrinsics) {
  std::vector<std::string> problems;
  for (std::size_t i = 0; i < session.views.size(); ++i) {
    const core::CalibrationView& view = session.views[i];
    const std::string label = "view " + std::to_string(i);
    if (const std::string why = file_problem(view.cloud); !why.empty())
      problems.push_back(view.cloud + ": " + why + " (" + label + " cloud, expected a PCD file)");
    for (const auto& [name, in] : intrinsics) {
      const auto it = view.images.find(name);
      if (it == view.images.end()) continue;  // a view without this camera is skipped, not an error
      const std::string& path = it->second;
      if (const std::string why = file_problem(path); !why.empty()) {
        problems.push_back(path + ": " + why + " (" + label + " " + name + " image, expected a PNG)");
        continue;
      }
      int w = 0, h = 0;
      std::string why;
      if (!read_png_size(path, &w, &h, &why)) {
        problems.push_back(path + ": " + why + " (" + label + " " + name + " image)");
        continue;
      }
      if (w != in.width || h != in.height) {
        problems.push_back(path + ": image size " + std::to_string(w) + "x" + std::to_string(h) + " (" + label +
                           " " + name + " image), expected " + std::to_string(in.width) + "x" +
                           std::to_string(in.height) + " as in the " + name + " camera_info");
      }
    }
  }
  return problems;
}

}  // namespace rgbdt::calibrate
