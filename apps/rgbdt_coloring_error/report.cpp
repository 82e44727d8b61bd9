#include "report.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "plot.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/error_model/paper_analysis.hpp"

namespace rgbdt::apps {
namespace {

using error_model::Source;

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

const cv::Scalar kColours[error_model::kNumSources] = {
    cv::Scalar(40, 160, 40),   // LIDAR noise: green
    cv::Scalar(200, 120, 0),   // intrinsics: blue
    cv::Scalar(30, 30, 210),   // rotation: red
    cv::Scalar(0, 150, 230),   // translation: orange
    cv::Scalar(0, 0, 0),       // total: black
};

}  // namespace

ReportFiles write_report(const std::string& dir, const error_model::ColoringErrorModel& model,
                         const ReportSettings& settings) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir, "cannot create the report folder (" + ec.message() + ")");
  ReportFiles files;
  files.markdown = (std::filesystem::path(dir) / ("coloring_error_" + settings.camera_name + ".md")).string();
  files.png = (std::filesystem::path(dir) / ("coloring_error_" + settings.camera_name + ".png")).string();
  const auto& sources = model.sources();
  const auto& K = sources.intrinsics;

  std::ostringstream md;
  md << "# Predicted colouring error: camera `" << settings.camera_name << "`\n\n"
     << "First-order propagation (rgbdt::error_model) of LIDAR noise, intrinsics and extrinsics "
        "uncertainty to the pixel a LIDAR point is coloured from and to the distance on the surface "
        "that lends it its colour (surface facing the camera, point on the ray of pixel ("
     << fixed(settings.pixel.x(), 1) << ", " << fixed(settings.pixel.y(), 1) << ")). Values are 1 sigma; "
     << "pixel columns are the RMS displacement sqrt(su^2 + sv^2), surface columns sqrt(sx^2 + sy^2).\n\n"
     << "Inputs:\n\n"
     << "- intrinsics: `" << settings.intrinsics_path << "` (" << K.width << "x" << K.height << ", fx " << fixed(K.fx, 3)
     << " px); covariance: " << settings.intrinsics_sigma_note << "\n"
     << "- extrinsics: `" << settings.extrinsics_path << "`; covariance: " << settings.extrinsics_sigma_note << "\n"
     << "- LIDAR noise: range " << fixed(sources.lidar.range_sigma_m * 100.0, 2) << " cm, beam angle "
     << fixed(sources.lidar.beam_angle_sigma_rad * 180.0 / M_PI, 4) << " deg, tilt angle "
     << fixed(sources.lidar.tilt_angle_sigma_rad * 180.0 / M_PI, 4) << " deg\n\n";
  if (sources.lidar.range_sigma_m > 0.0) {
    md << "Paper, Sec. 4.3 (x only, X = 5): LIDAR noise stops moving a projection by 1 px beyond "
       << fixed(error_model::lidar_noise_depth_m(K.fx, sources.lidar.range_sigma_m), 6) << " m (Eq. (9))";
    if (sources.intrinsics_covariance.size() != 0) {
      const double dfx = std::sqrt(sources.intrinsics_covariance(0, 0));
      md << "; with dfx = " << fixed(dfx, 3) << " px, beyond "
         << fixed(error_model::intrinsics_depth_m(K.fx, dfx, sources.lidar.range_sigma_m), 6)
         << " m (Eq. (14) as the paper evaluates it)";
    }
    md << ".\n\n";
  }

  md << "| depth [m] |";
  for (int s = 0; s < error_model::kNumSources; ++s) md << " " << display_name(static_cast<Source>(s)) << " [px] |";
  for (int s = 0; s < error_model::kNumSources; ++s) md << " " << display_name(static_cast<Source>(s)) << " [cm] |";
  md << " total x [cm] | total y [cm] |";
  if (settings.monte_carlo_samples > 0) md << " total, Monte Carlo [cm] |";
  md << "\n|---|";
  for (int i = 0; i < 2 * error_model::kNumSources + 2 + (settings.monte_carlo_samples > 0); ++i) md << "---:|";
  md << "\n";
  for (double depth : settings.table_depths_m) {
    const auto p = model.predict(settings.pixel, depth);
    md << "| " << fixed(depth, 2) << " |";
    for (const auto& e : p.sources) md << " " << fixed(e.pixel_rms_px(), 3) << " |";
    for (const auto& e : p.sources) md << " " << fixed(100.0 * e.surface_rms_m(), 3) << " |";
    md << " " << fixed(100.0 * p[Source::kTotal].surface_sigma_x_m(), 3) << " | "
       << fixed(100.0 * p[Source::kTotal].surface_sigma_y_m(), 3) << " |";
    if (settings.monte_carlo_samples > 0) {
      const auto mc = model.monte_carlo(settings.pixel, depth, -Eigen::Vector3d::UnitZ(), settings.monte_carlo_samples);
      md << " " << fixed(100.0 * mc[Source::kTotal].surface_rms_m(), 3) << " |";
    }
    md << "\n";
  }
  // Dependence on the image position: the centre and the four corners (5 % in from the border).
  {
    const double mu = 0.05 * K.width, mv = 0.05 * K.height;
    const std::pair<const char*, Eigen::Vector2d> positions[] = {
        {"centre", Eigen::Vector2d(K.cx, K.cy)},
        {"top left", Eigen::Vector2d(mu, mv)},
        {"top right", Eigen::Vector2d(K.width - 1 - mu, mv)},
        {"bottom left", Eigen::Vector2d(mu, K.height - 1 - mv)},
        {"bottom right", Eigen::Vector2d(K.width - 1 - mu, K.height - 1 - mv)}};
    std::vector<double> depths;
    for (double d : {5.0, 10.0, 15.0}) {
      if (d >= settings.plot_min_m && d <= settings.plot_max_m) depths.push_back(d);
    }
    if (!depths.empty()) {
      md << "\nTotal error by image position (surface facing the camera):\n\n| pixel |";
      for (double d : depths) md << " " << fixed(d, 1) << " m [px] | " << fixed(d, 1) << " m [cm] |";
      md << "\n|---|";
      for (std::size_t i = 0; i < 2 * depths.size(); ++i) md << "---:|";
      md << "\n";
      for (const auto& [name, uv] : positions) {
        md << "| " << name << " (" << fixed(uv.x(), 0) << ", " << fixed(uv.y(), 0) << ") |";
        for (double d : depths) {
          const auto p = model.predict(uv, d);
          md << " " << fixed(p[Source::kTotal].pixel_rms_px(), 3) << " | " << fixed(100.0 * p[Source::kTotal].surface_rms_m(), 3)
             << " |";
        }
        md << "\n";
      }
    }
  }
  md << "\n![predicted colouring error](" << std::filesystem::path(files.png).filename().string() << ")\n";
  md << "\n## Configuration\n\nThe options this run used (`--config` reads this block back):\n\n```yaml\n" << settings.config_yaml << "```\n";
  core::write_file_atomic(files.markdown, md.str());

  // Plot: pixel error and surface error vs depth, one curve per source.
  PlotPanel pixels{"Pixel error (1 sigma RMS)", "depth [m]", "pixel error [px]", {}};
  PlotPanel surface{"Mis-colouring distance on the surface (1 sigma RMS)", "depth [m]", "distance [cm]", {}};
  for (int s = 0; s < error_model::kNumSources; ++s) {
    Curve c{display_name(static_cast<Source>(s)), {}, {}, kColours[s], false};
    pixels.curves.push_back(c);
    surface.curves.push_back(c);
  }
  const int steps = 200;
  for (int i = 0; i <= steps; ++i) {
    const double depth = settings.plot_min_m + (settings.plot_max_m - settings.plot_min_m) * i / steps;
    const auto p = model.predict(settings.pixel, depth);
    for (int s = 0; s < error_model::kNumSources; ++s) {
      pixels.curves[s].x.push_back(depth);
      pixels.curves[s].y.push_back(p.sources[s].pixel_rms_px());
      surface.curves[s].x.push_back(depth);
      surface.curves[s].y.push_back(100.0 * p.sources[s].surface_rms_m());
    }
  }
  const cv::Mat image = draw_panels({pixels, surface});
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png)) throw core::Error(files.png, "cannot encode the PNG plot");
  core::write_file_atomic(files.png, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  return files;
}

}  // namespace rgbdt::apps
