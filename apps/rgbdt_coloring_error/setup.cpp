#include "setup.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/core/yaml_util.hpp"
#include "rgbdt/error_model/coloring_band.hpp"
#include "rgbdt/error_model/error_propagation.hpp"

namespace fs = std::filesystem;

namespace rgbdt::apps {
namespace {

std::string resolve(const fs::path& dir, const std::string& file) {
  const fs::path p(file);
  return (p.is_absolute() ? p : dir / p).lexically_normal().string();
}

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

/// Paper Tables 2 (RGB, our algorithm) and 3 (thermal): depth [m] -> x, y [cm].
struct PaperRow {
  double depth_m, x_cm, y_cm;
};
const std::vector<PaperRow> kPaperRgb = {{5, 0, 2}, {7.5, 1, 3}, {10, 3, 6}, {12, 5, 8}, {15, 6, 10}};
const std::vector<PaperRow> kPaperThermal = {{5, 2, 4}, {7.5, 3, 6}, {10, 3, 7}, {12, 4, 10}, {15, 5, 13}};

std::optional<PaperRow> paper_row(const std::string& camera, double depth_m) {
  const auto& rows = camera.find("thermal") != std::string::npos ? kPaperThermal : kPaperRgb;
  for (const auto& r : rows) {
    if (std::abs(r.depth_m - depth_m) < 0.75) return r;
  }
  return std::nullopt;
}

error_model::GrayImage load_gray(const std::string& path) {
  const cv::Mat raw = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  if (raw.empty()) throw core::Error(path, "cannot read the image (expected a PNG)");
  cv::Mat gray = raw;
  if (raw.channels() == 3) cv::cvtColor(raw, gray, cv::COLOR_BGR2GRAY);
  if (raw.channels() == 4) cv::cvtColor(raw, gray, cv::COLOR_BGRA2GRAY);
  cv::Mat f;
  gray.convertTo(f, CV_32F);
  error_model::GrayImage image{f.cols, f.rows, {}};
  image.pixels.assign(f.begin<float>(), f.end<float>());
  return image;
}

std::vector<Eigen::Vector3d> load_points(const std::string& path) {
  const cloud::LoadedCloud loaded = cloud::load_cloud(path);
  std::vector<Eigen::Vector3d> points;
  points.reserve(loaded.cloud->size());
  for (const auto& p : *loaded.cloud) points.emplace_back(p.x, p.y, p.z);
  return points;
}

/// 1-sigma spread of the colour source across the edges (card x, y axes) from the model.
Eigen::Vector2d predicted_sigma(const error_model::ColoringErrorModel& model,
                                const error_model::CardBandMeasurement& m) {
  const Eigen::Matrix3d R = model.sources().T_camera_lidar.linear();
  const auto p = model.predict_point(m.card_centre_lidar, R * m.card_normal_lidar);
  const Eigen::Matrix2d& C = p[error_model::Source::kTotal].surface_covariance;
  Eigen::Vector2d out;
  for (int axis = 0; axis < 2; ++axis) {
    const Eigen::Vector3d e = R * (axis == 0 ? m.card_x_lidar : m.card_y_lidar);
    const Eigen::Vector2d a(e.dot(p.surface_x_camera), e.dot(p.surface_y_camera));
    out[axis] = std::sqrt(std::max(0.0, a.dot(C * a)));
  }
  return out;
}

/// A view of the card like the paper's Fig. 11-12: points in card coordinates in their
/// sampled grey, mis-coloured ones ringed in red, mixed pixels in blue, the card extent in green.
void write_band_plot(const std::string& path, const std::string& title, const error_model::CardBandMeasurement& m) {
  const double margin = 0.3;
  const double xa = m.x0_m - margin, xb = m.x1_m + margin, ya = m.y0_m - margin, yb = m.y1_m + margin;
  const double scale = 700.0 / std::max(xb - xa, yb - ya);  // px per metre
  const int width = static_cast<int>((xb - xa) * scale) + 1, top = 40, legend = 30;
  const int height = static_cast<int>((yb - ya) * scale) + 1 + top + legend;
  cv::Mat canvas(height, width, CV_8UC3, cv::Scalar(90, 140, 90));
  auto px = [&](const Eigen::Vector2d& xy) {
    return cv::Point(static_cast<int>((xy.x() - xa) * scale), top + static_cast<int>((yb - xy.y()) * scale));
  };
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& p : m.points) {
    lo = std::min(lo, p.intensity);
    hi = std::max(hi, p.intensity);
  }
  const double span = hi > lo ? hi - lo : 1.0;
  const int radius = std::max(2, static_cast<int>(0.004 * scale));
  for (const auto& p : m.points) {
    const int g = static_cast<int>(255.0 * (p.intensity - lo) / span);
    cv::circle(canvas, px(p.xy_m), radius, cv::Scalar(g, g, g), cv::FILLED);
  }
  for (const auto& p : m.points) {
    using C = error_model::CardPointClass;
    if (p.label == C::kCardMiscoloured || p.label == C::kBackgroundMiscoloured) {
      cv::circle(canvas, px(p.xy_m), radius + 3, cv::Scalar(0, 0, 255), 2);
    } else if (p.label == C::kMixed) {
      cv::circle(canvas, px(p.xy_m), radius, cv::Scalar(255, 80, 0), cv::FILLED);
    }
  }
  cv::rectangle(canvas, px({m.x0_m, m.y1_m}), px({m.x1_m, m.y0_m}), cv::Scalar(0, 200, 0), 1);
  cv::rectangle(canvas, cv::Rect(0, 0, width, top), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(canvas, cv::Rect(0, height - legend, width, legend), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(canvas, title, cv::Point(10, 26), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  const int ly = height - 10;
  cv::circle(canvas, cv::Point(15, ly - 5), 6, cv::Scalar(0, 0, 255), 2);
  cv::putText(canvas, "mis-coloured", cv::Point(27, ly), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::circle(canvas, cv::Point(150, ly - 5), 4, cv::Scalar(255, 80, 0), cv::FILLED);
  cv::putText(canvas, "mixed pixel (ignored)", cv::Point(160, ly), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  cv::rectangle(canvas, cv::Point(340, ly - 10), cv::Point(360, ly), cv::Scalar(0, 200, 0), 1);
  cv::putText(canvas, "card extent", cv::Point(368, ly), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  std::vector<uchar> png;
  if (!cv::imencode(".png", canvas, png)) throw core::Error(path, "cannot encode the PNG");
  core::write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

struct Row {
  double range_m = 0.0;
  error_model::CardBandMeasurement measured;
  std::optional<error_model::CardBandMeasurement> with_truth;
  std::optional<Eigen::Vector2d> expected_m;  // from the true calibration's difference
  std::optional<Eigen::Vector2d> sigma_m;     // model
};

}  // namespace

SetupSession read_setup_session(const std::string& path) {
  fs::path yaml_path(path);
  if (fs::is_directory(yaml_path)) yaml_path /= "session.yaml";
  const std::string src = yaml_path.string();
  if (!fs::exists(yaml_path)) throw core::Error(src, "missing (expected the setup's session.yaml or its folder)");
  const YAML::Node root = core::load_yaml_file(src);
  SetupSession s;
  s.directory = fs::absolute(yaml_path).parent_path().lexically_normal().string();
  const core::YamlField fields(root, src);
  if (!fields.has("views")) {
    // Mapping layout (what rgbdt_sim coloring-setup writes): assembled clouds + frame indexes.
    const core::MappingSession mapping = core::read_mapping_session(src);
    if (mapping.lidar.clouds.empty()) {
      throw core::Error(src, "lidar has no 'clouds' index: expected assembled clouds (lidar: {clouds: index.csv}) "
                             "or a 'views' list");
    }
    const auto clouds = core::read_time_index(mapping.lidar.clouds);
    std::map<std::string, std::vector<core::TimedFile>> camera_frames;
    for (const auto& [name, entry] : mapping.cameras) {
      s.intrinsics[name] = entry.intrinsics;
      if (!entry.frames.empty()) camera_frames[name] = core::read_time_index(entry.frames);
    }
    for (const auto& c : clouds) {
      SetupView view;
      view.cloud = c.file;
      for (const auto& [name, list] : camera_frames) {
        const int k = core::nearest_in_time(list, c.time_s);
        if (k >= 0) view.images[name] = list[static_cast<std::size_t>(k)].file;
      }
      s.views.push_back(view);
    }
  } else {
    // Calibration layout: one entry per placement with its cloud and images.
    const fs::path dir(s.directory);
    const std::string camera_map = "a map camera -> {intrinsics: file.yaml}";
    for (const auto& [name, entry] : fields.at("cameras", camera_map).entries(camera_map)) {
      // The name becomes part of file names (extrinsics_<name>.yaml, the plots).
      if (!core::is_valid_camera_name(name)) {
        entry.fail("under a camera name '" + name + "', expected 1 to 64 characters of [A-Za-z0-9_-]");
      }
      s.intrinsics[name] = resolve(dir, entry.at("intrinsics", "a camera_info YAML file").as_string("a file path"));
    }
    const core::YamlField views = fields.at("views", "a list of placements");
    const std::size_t n = views.expect_sequence("a list of {cloud: file.pcd, images: {camera: image.png}}");
    for (std::size_t i = 0; i < n; ++i) {
      const core::YamlField v = views.item(i);
      SetupView view;
      view.cloud = resolve(dir, v.at("cloud", "a PCD or PLY file").as_string("a file path"));
      const std::string image_map = "a map camera -> image.png";
      for (const auto& [name, image] : v.at("images", image_map).entries(image_map)) {
        view.images[name] = resolve(dir, image.as_string("a file path"));
      }
      s.views.push_back(view);
    }
  }
  if (s.views.empty()) throw core::Error(src, "no views: expected one cloud per card placement");
  return s;
}

int run_setup(const SetupSession& session, const SetupSettings& settings) {
  if (!fs::is_directory(settings.calib_dir)) throw core::Error(settings.calib_dir, "--calib: expected a calibration folder");
  std::vector<std::string> cameras;
  for (const auto& [name, file] : session.intrinsics) {
    if (!settings.camera.empty() && name != settings.camera) continue;
    cameras.push_back(name);
  }
  if (cameras.empty()) {
    throw core::Error(session.directory, "no camera '" + settings.camera + "' in session.yaml");
  }
  std::ostringstream md;
  int measured_tables = 0;
  for (const std::string& camera_name : cameras) {
    const fs::path extrinsics_path = fs::path(settings.calib_dir) / ("extrinsics_" + camera_name + ".yaml");
    if (!fs::exists(extrinsics_path)) {
      std::cerr << "skipping camera " << camera_name << ": " << extrinsics_path.string() << " does not exist\n";
      continue;
    }
    core::Extrinsics extrinsics = core::read_extrinsics(extrinsics_path.string(), core::ExtrinsicsFrames{camera_name});
    if (settings.extrinsics_covariance) extrinsics.covariance = *settings.extrinsics_covariance;
    if (settings.extrinsics_offset) extrinsics.T_parent_child = core::from_vector6(*settings.extrinsics_offset) * extrinsics.T_parent_child;
    const core::CameraIntrinsics intrinsics = core::read_camera_info(session.intrinsics.at(camera_name));
    const core::PinholeCamera camera(intrinsics);
    std::optional<core::Extrinsics> truth;
    const fs::path truth_path = fs::path(session.directory) / "true_calib" / ("extrinsics_" + camera_name + ".yaml");
    if (fs::exists(truth_path)) truth = core::read_extrinsics(truth_path.string(), core::ExtrinsicsFrames{camera_name});
    std::optional<core::PinholeCamera> true_camera;
    const fs::path true_intrinsics = fs::path(session.directory) / "true_calib" / (camera_name + ".yaml");
    if (truth) true_camera.emplace(fs::exists(true_intrinsics) ? core::read_camera_info(true_intrinsics.string()) : intrinsics);

    std::optional<error_model::ColoringErrorModel> model;
    if (extrinsics.covariance) {
      error_model::ErrorSources sources;
      sources.intrinsics = intrinsics;
      sources.T_camera_lidar = extrinsics.T_parent_child;
      sources.extrinsics_covariance = *extrinsics.covariance;
      sources.lidar.range_sigma_m = settings.lidar_noise_m;
      if (!settings.intrinsics_sigma.empty()) {
        const Eigen::VectorXd sigma =
            Eigen::Map<const Eigen::VectorXd>(settings.intrinsics_sigma.data(), settings.intrinsics_sigma.size());
        sources.intrinsics_covariance = Eigen::MatrixXd(sigma.cwiseAbs2().asDiagonal());
      }
      model.emplace(sources);
    } else {
      std::cerr << "note: " << extrinsics_path.string() << " has no covariance: no predicted band\n";
    }

    std::vector<Row> rows;
    for (std::size_t i = 0; i < session.views.size(); ++i) {
      const SetupView& view = session.views[i];
      const auto image_it = view.images.find(camera_name);
      if (image_it == view.images.end()) continue;
      try {
        const auto points = load_points(view.cloud);
        const auto image = load_gray(image_it->second);
        Row row;
        error_model::CardBandOptions band_options;
        band_options.keep_points = !settings.report_dir.empty();
        row.measured = error_model::measure_card_band(
            points, error_model::sample_point_intensities(points, camera, extrinsics.T_parent_child, image),
            band_options);
        row.range_m = row.measured.card_range_m;
        if (truth) {
          // The same measurement with the true calibration: what sampling, mixed pixels and
          // the cloth's occlusion shadow alone leave.
          row.with_truth = error_model::measure_card_band(
              points, error_model::sample_point_intensities(points, *true_camera, truth->T_parent_child, image));
          const Eigen::Vector3d offset = error_model::colour_source_offset(
              row.measured.card_centre_lidar, row.measured.card_normal_lidar, *true_camera, truth->T_parent_child,
              camera, extrinsics.T_parent_child);
          row.expected_m = Eigen::Vector2d(std::abs(offset.dot(row.measured.card_x_lidar)),
                                           std::abs(offset.dot(row.measured.card_y_lidar)));
        }
        if (model) row.sigma_m = predicted_sigma(*model, row.measured);
        if (!settings.report_dir.empty()) {
          fs::create_directories(settings.report_dir);
          char range[32];
          std::snprintf(range, sizeof(range), "%05.2f", row.range_m);
          const std::string name = "setup_" + camera_name + "_" + range + "m.png";
          std::ostringstream title;
          title << camera_name << ", card at " << fixed(row.range_m, 2) << " m: band x " << fixed(100 * row.measured.band_x_m, 1)
                << " cm, y " << fixed(100 * row.measured.band_y_m, 1) << " cm";
          write_band_plot((fs::path(settings.report_dir) / name).string(), title.str(), row.measured);
          row.measured.points.clear();
        }
        rows.push_back(row);
        std::cerr << camera_name << " view " << i << ": card at " << fixed(row.range_m, 2) << " m, band x "
                  << fixed(100 * row.measured.band_x_m, 1) << " cm, y " << fixed(100 * row.measured.band_y_m, 1)
                  << " cm (" << row.measured.card_points << " card points)\n";
      } catch (const core::Error& e) {
        std::cerr << camera_name << " view " << i << " (" << view.cloud << "): " << e.what() << "\n";
      }
    }
    if (rows.empty()) continue;
    ++measured_tables;
    std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.range_m < b.range_m; });
    const bool thermal = camera_name.find("thermal") != std::string::npos;
    md << "\n### Table " << (thermal ? 3 : 2) << " (" << camera_name << "): mis-coloured band along the card edges\n\n"
       << "Extrinsics `" << extrinsics_path.string() << "`";
    if (settings.extrinsics_offset) {
      const auto& d = *settings.extrinsics_offset;
      md << ", moved by the what-if offset rx ry rz = " << fixed(d[0] * 180 / M_PI, 3) << " " << fixed(d[1] * 180 / M_PI, 3)
         << " " << fixed(d[2] * 180 / M_PI, 3) << " deg, tx ty tz = " << fixed(d[3] * 100, 2) << " " << fixed(d[4] * 100, 2)
         << " " << fixed(d[5] * 100, 2) << " cm (camera frame)";
    }
    md << ". Measured automatically (rgbdt::error_model::"
          "measure_card_band): x = band across the left/right edges, y = across the bottom/top edges, mean of the "
          "two edges, in cm.";
    if (model) md << " Predicted: 95 % bound 1.96 sigma of the first-order model (extrinsics covariance, LIDAR noise "
                  << fixed(settings.lidar_noise_m * 100, 1) << " cm" << (settings.intrinsics_sigma.empty() ? "" : ", intrinsics")
                  << ").";
    if (truth) md << " Expected: the colour offset the difference to `true_calib/` causes at the card centre; "
                     "'truth': the band measured with the true calibration (sampling, mixed pixels, occlusion shadow).";
    md << "\n\n| depth [m] | x [cm] | y [cm] |";
    if (model) md << " predicted x [cm] | predicted y [cm] |";
    if (truth) md << " expected x [cm] | expected y [cm] | truth x [cm] | truth y [cm] |";
    md << " paper x [cm] | paper y [cm] | card points |\n|---:|---:|---:|";
    for (int k = 0; k < (model ? 2 : 0) + (truth ? 4 : 0) + 3; ++k) md << "---:|";
    md << "\n";
    for (const Row& r : rows) {
      md << "| " << fixed(r.range_m, 2) << " | " << fixed(100 * r.measured.band_x_m, 1) << " | "
         << fixed(100 * r.measured.band_y_m, 1) << " |";
      if (model) md << " " << fixed(196 * r.sigma_m->x(), 1) << " | " << fixed(196 * r.sigma_m->y(), 1) << " |";
      if (truth) {
        md << " " << fixed(100 * r.expected_m->x(), 1) << " | " << fixed(100 * r.expected_m->y(), 1) << " | "
           << fixed(100 * r.with_truth->band_x_m, 1) << " | " << fixed(100 * r.with_truth->band_y_m, 1) << " |";
      }
      const auto paper = paper_row(camera_name, r.range_m);
      md << " " << (paper ? fixed(paper->x_cm, 0) : "-") << " | " << (paper ? fixed(paper->y_cm, 0) : "-") << " | "
         << r.measured.card_points << " |\n";
    }
  }
  std::cout << md.str();
  if (!settings.report_dir.empty()) {
    fs::create_directories(settings.report_dir);
    const std::string out_path = (fs::path(settings.report_dir) / "coloring_setup.md").string();
    core::write_file_atomic(out_path, "# Coloring-error setup (paper Sec. 4.4)\n\nSession `" + session.directory +
                                          "`\n" + md.str() +
                                          "\n## Configuration\n\nThe options this run used (`--config` reads this block back):\n\n```yaml\n" + settings.config_yaml + "```\n");
    std::cout << "\nwrote " << out_path << "\n";
  }
  if (measured_tables == 0) {
    std::cerr << "error: no view could be measured with any camera\n";
    return 1;
  }
  return 0;
}

}  // namespace rgbdt::apps
