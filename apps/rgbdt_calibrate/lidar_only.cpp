#include "lidar_only.hpp"

#include <cstdio>
#include <filesystem>
#include <sstream>

#include "detections_table.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/output.hpp"

namespace rgbdt::calibrate {

namespace fs = std::filesystem;

int run_lidar_only(const core::CalibrationSession& session, const std::string& out_dir, bool use_seeds) {
  const fs::path out(out_dir);
  const std::string report_path = (out / "report.md").string(), csv_path = (out / "detections_lidar.csv").string();
  core::remove_stale_output(report_path);
  core::remove_stale_output(csv_path);
  std::vector<DetectionRow> rows;
  std::vector<std::string> missed;
  std::ostringstream views;
  for (size_t i = 0; i < session.views.size(); ++i) {
    if (core::interrupted()) {
      std::fprintf(stderr, "interrupted after %zu of %zu views; nothing was written\n", i, session.views.size());
      return 130;
    }
    const core::CalibrationView& view = session.views[i];
    calib_targets::LidarTargetDetection det;
    try {
      const cloud::LoadedCloud loaded = cloud::load_cloud(view.cloud);
      std::optional<Eigen::Vector3d> seed;
      if (use_seeds) seed = view.lidar_seed;
      det = calib_targets::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, session.target, {}, seed);
      if (!det.ok && seed) det = calib_targets::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, session.target);
    } catch (const std::exception& e) {
      det.ok = false;
      det.reason = std::string("cannot read the cloud: ") + e.what();
    }
    std::string line = "view " + std::to_string(i) + " (" + view.cloud + "): ";
    if (det.ok) {
      line += std::to_string(det.holes.size()) + " hole(s), method " + det.edge_method;
      for (size_t h = 0; h < det.holes.size(); ++h) {
        DetectionRow row;
        row.view = static_cast<int>(i);
        row.hole = static_cast<int>(h);
        row.lidar_center = det.holes[h].center;
        row.lidar_radius_m = det.holes[h].radius_m;
        row.radius_measured = det.holes[h].radius_measured;
        row.lidar_method = det.edge_method;
        rows.push_back(row);
      }
    } else {
      line += "target not found (" + det.reason + ")";
      missed.push_back("view " + std::to_string(i));
    }
    std::printf("%s\n", line.c_str());
    views << "- " << line << "\n";
  }
  core::write_file_atomic(csv_path, format_detections_csv(rows));
  std::printf("wrote %s (%zu holes)\n", csv_path.c_str(), rows.size());
  std::ostringstream doc;
  doc << "# rgbdt_calibrate --lidar-only report\n\nSession: `" << session.directory << "`, "
      << session.views.size() << " views; target found in " << session.views.size() - missed.size() << ".\n\n"
      << views.str() << "\n" << format_detections_markdown(rows);
  core::write_file_atomic(report_path, doc.str());
  std::printf("wrote %s\n", report_path.c_str());
  if (!missed.empty()) {
    std::fprintf(stderr, "error: the target was not found in %zu of %zu views:", missed.size(), session.views.size());
    for (const auto& m : missed) std::fprintf(stderr, " %s", m.c_str());
    std::fprintf(stderr, " (see %s)\n", report_path.c_str());
    return 2;
  }
  return 0;
}

}  // namespace rgbdt::calibrate
