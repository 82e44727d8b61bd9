#pragma once
// rgbdt_calibrate --lidar-only: the target detected in every cloud of a session, without
// any camera (boards without a camera, or checking a LIDAR before a calibration).
#include <string>

#include "rgbdt/core/session.hpp"

namespace rgbdt::calibrate {

/// Detects the target in every cloud of `session` and writes OUT_DIR/detections_lidar.csv
/// (one row per hole and view) and, last, OUT_DIR/report.md (per view: holes found or the
/// reason). Returns the exit code: 0 when the target was found in every view, 2 when it was
/// missed in some (named in the report and on stderr), 130 when interrupted.
int run_lidar_only(const core::CalibrationSession& session, const std::string& out_dir, bool use_seeds);

}  // namespace rgbdt::calibrate
