#pragma once
// The --report mode: predicted colouring error vs depth as Markdown + PNG.
#include <string>
#include <vector>

#include "rgbdt/error_model/error_propagation.hpp"

namespace rgbdt::apps {

struct ReportSettings {
  std::string camera_name;
  std::string intrinsics_path, extrinsics_path;
  std::string intrinsics_sigma_note;   // where the intrinsics covariance came from
  std::string extrinsics_sigma_note;   // where the extrinsics covariance came from
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  std::vector<double> table_depths_m;  // rows of the Markdown table
  double plot_min_m = 1.0, plot_max_m = 20.0;
  int monte_carlo_samples = 0;         // 0: no Monte Carlo column
  std::string config_yaml;             // the app's effective configuration, recorded in the report
};

struct ReportFiles {
  std::string markdown, png;
};

/// Writes <dir>/coloring_error_<camera>.md and .png; returns their paths. Throws
/// rgbdt::core::Error when a file cannot be written.
ReportFiles write_report(const std::string& dir, const error_model::ColoringErrorModel& model,
                         const ReportSettings& settings);

}  // namespace rgbdt::apps
