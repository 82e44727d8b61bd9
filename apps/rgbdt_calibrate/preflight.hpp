#pragma once
// Checks every file a calibration session names before any detection runs, so that a
// missing or mismatched file is reported at once instead of after minutes of work.
#include <map>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/session.hpp"

namespace rgbdt::calibrate {

/// Width and height from a PNG's signature and IHDR chunk (bytes 16..23). Returns false
/// and sets `why` when the file cannot be read or is not a PNG.
// A local helper until rgbdt/core/image_header.hpp (read_image_header) is on main.
bool read_png_size(const std::string& path, int* width, int* height, std::string* why);

/// Every problem with the files of `session` for the cameras in `intrinsics`: clouds that
/// are missing, unreadable or empty; images that are missing, unreadable, not PNG or of a
/// size other than the camera_info's. Each entry names the file, the value and what was
/// expected. Empty when all is well.
std::vector<std::string> preflight_problems(const core::CalibrationSession& session,
                                            const std::map<std::string, core::CameraIntrinsics>& intrinsics);

}  // namespace rgbdt::calibrate
