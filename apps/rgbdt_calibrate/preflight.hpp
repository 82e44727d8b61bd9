#pragma once
// Checks every file a calibration session names before any detection runs, so that a
// missing or mismatched file is reported at once instead of after minutes of work.
#include <map>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/session.hpp"

namespace rgbdt::calibrate {

/// Every problem with the files of `session` for the cameras in `intrinsics`: clouds that
/// are missing or that the checked reader refuses; images that are missing, unreadable,
/// not PNG/JPEG, too large to decode or of a size other than the camera_info's. Each entry names the file, the value and what was
/// expected. Empty when all is well.
std::vector<std::string> preflight_problems(const core::CalibrationSession& session,
                                            const std::map<std::string, core::CameraIntrinsics>& intrinsics);

}  // namespace rgbdt::calibrate
