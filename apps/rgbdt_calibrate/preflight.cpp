#include "preflight.hpp"

#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/image_header.hpp"

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

std::vector<std::string> preflight_problems(const core::CalibrationSession& session,
                                            const std::map<std::string, core::CameraIntrinsics>& intrinsics) {
  std::vector<std::string> problems;
  for (std::size_t i = 0; i < session.views.size(); ++i) {
    const core::CalibrationView& view = session.views[i];
    const std::string label = "view " + std::to_string(i);
    if (const std::string why = file_problem(view.cloud); !why.empty()) {
      problems.push_back(view.cloud + ": " + why + " (" + label + " cloud, expected a PCD or PLY file)");
    } else {
      // The whole cloud goes through the checked reader: a calibration cloud holds at most a
      // few hundred thousand points, read in milliseconds, and a corrupt one must stop the
      // run before any detection rather than quietly drop its view.
      try {
        (void)cloud::load_cloud(view.cloud);
      } catch (const std::exception& e) {
        problems.push_back(std::string(e.what()) + " (" + label + " cloud)");
      }
    }
    for (const auto& [name, in] : intrinsics) {
      const auto it = view.images.find(name);
      if (it == view.images.end()) continue;  // a view without this camera is skipped, not an error
      const std::string& path = it->second;
      if (const std::string why = file_problem(path); !why.empty()) {
        problems.push_back(path + ": " + why + " (" + label + " " + name + " image, expected a PNG)");
        continue;
      }
      try {
        const core::ImageHeader header = core::read_image_header(path);
        const std::string mismatch = core::image_mismatch(header, in.width, in.height, path, session.cameras.at(name).intrinsics);
        if (!mismatch.empty()) problems.push_back(mismatch + " (" + label + " " + name + " image)");
      } catch (const std::exception& e) {
        problems.push_back(std::string(e.what()) + " (" + label + " " + name + " image)");
      }
    }
  }
  return problems;
}

}  // namespace rgbdt::calibrate
