// rgbdt_calibrate_intrinsics: intrinsic calibration of an RGB or thermal camera from a
// folder of images of a checkerboard or circle grid (paper Sec. 3.1).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/intrinsics.hpp"
#include "rgbdt/core/camera_info.hpp"

namespace fs = std::filesystem;
namespace ct = rgbdt::calib_targets;

namespace {

cv::Mat to_bgr(const cv::Mat& image) {
  cv::Mat f = ct::normalise_image(image, 0.5, 99.5), u8, bgr;
  f.convertTo(u8, CV_8U, 255.0);
  cv::cvtColor(u8, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

void write_report(const fs::path& dir, const ct::IntrinsicsResult& r, const std::vector<cv::Mat>& images,
                  const std::vector<ct::PatternDetection>& det, const std::string& baseline) {
  fs::create_directories(dir / "views");
  std::ofstream md(dir / "report.md");
  md << "# Intrinsic calibration\n\n";
  md << "- model: " << rgbdt::core::to_string(r.intrinsics.model) << ", estimated terms: " << r.distortion_terms << "\n";
  md << "- RMS reprojection error: " << r.rms_px << " px\n";
  md << "- coverage (8x8 grid cells with points): " << r.coverage * 100.0 << " %\n";
  int used = 0;
  for (const auto& v : r.views) used += v.used ? 1 : 0;
  md << "- views used: " << used << " of " << r.views.size() << "\n";
  if (!baseline.empty()) md << "- baseline (plain OpenCV): " << baseline << "\n";
  md << "\n## Parameters (1 sigma)\n\n| parameter | value | std dev |\n|---|---|---|\n";
  for (std::size_t k = 0; k < r.parameters.size(); ++k) {
    md << "| " << r.parameter_names[k] << " | " << r.parameters[k] << " | "
       << (k < r.std_devs.size() ? r.std_devs[k] : 0.0) << " |\n";
  }
  if (!r.candidates.empty()) {
    md << "\n## Distortion terms (cross-validation over views)\n\n| terms | held-out RMS [px] | training RMS [px] |\n|---|---|---|\n";
    for (const auto& c : r.candidates) md << "| " << c.terms << " | " << c.heldout_rms_px << " | " << c.train_rms_px << " |\n";
  }
  md << "\n## Views\n\n| view | used | RMS [px] | detector / reason |\n|---|---|---|---|\n";
  std::ofstream csv(dir / "per_view_errors.csv");
  csv << "view,used,rms_px,reason\n";
  cv::Mat coverage = images.empty() ? cv::Mat() : to_bgr(images[0]) * 0.4;
  cv::Mat residuals(600, 600, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::line(residuals, {300, 0}, {300, 599}, {200, 200, 200});
  cv::line(residuals, {0, 300}, {599, 300}, {200, 200, 200});
  cv::circle(residuals, {300, 300}, 100, {200, 200, 200});  // 1 px at 100 px per px
  for (std::size_t v = 0; v < r.views.size(); ++v) {
    const auto& view = r.views[v];
    md << "| " << view.name << " | " << (view.used ? "yes" : "no") << " | " << view.rms_px << " | "
       << (view.used ? det[v].method + (det[v].inverted ? " (inverted polarity)" : "") : view.reason) << " |\n";
    csv << view.name << "," << (view.used ? 1 : 0) << "," << view.rms_px << ",\"" << view.reason << "\"\n";
    if (!det[v].ok) continue;
    cv::Mat vis = to_bgr(images[v]);
    cv::drawChessboardCorners(vis, cv::Size(0, 0), det[v].points, false);
    for (const auto& p : det[v].points) cv::circle(vis, p, 3, view.used ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
    cv::imwrite((dir / "views" / (fs::path(view.name).stem().string() + "_corners.png")).string(), vis);
    if (!view.used) continue;
    for (std::size_t k = 0; k < view.points.size(); ++k) {
      cv::circle(coverage, view.points[k], 3, {0, 255, 0}, -1);
      const cv::Point2f d = view.points[k] - view.reprojected[k];
      cv::circle(residuals, cv::Point2f(300.f + 100.f * d.x, 300.f + 100.f * d.y), 1, {200, 0, 0}, -1);
    }
  }
  cv::putText(residuals, "residuals: 100 px per px, circle = 1 px", {10, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0});
  if (!coverage.empty()) cv::imwrite((dir / "coverage.png").string(), coverage);
  cv::imwrite((dir / "residuals.png").string(), residuals);
  md << "\nImages: `coverage.png`, `residuals.png`, `views/*_corners.png`; per-view errors in `per_view_errors.csv`.\n";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Intrinsic calibration of an RGB or thermal camera from images of a checkerboard or a circle grid.\n"
      "16-bit and low-contrast thermal images are normalised by percentiles; both polarities are tried\n"
      "(black squares may be warm); corners are refined on the normalised data; unreliable views are\n"
      "rejected with the reason; the distortion terms are chosen by cross-validation over views.\n"
      "Writes a ROS camera_info YAML and, with --report, report.md, per-view errors and PNGs."};
  std::string images_dir, pattern_name = "checkerboard", model_name = "plumb_bob", out, report_dir, camera_name = "camera";
  int cols = 0, rows = 0;
  double square = 0.0;
  bool all_terms = false;
  app.add_option("--images", images_dir, "folder of images (png, jpg, tif, bmp)")->required()->check(CLI::ExistingDirectory);
  app.add_option("--pattern", pattern_name, "checkerboard | circles | acircles")->capture_default_str();
  app.add_option("--cols", cols, "inner corners (checkerboard) or circles per row")->required();
  app.add_option("--rows", rows, "inner corners or circles per column")->required();
  app.add_option("--square", square, "square size or circle spacing [m]")->required();
  app.add_option("--model", model_name, "plumb_bob | equidistant")->capture_default_str();
  app.add_option("--out", out, "camera_info YAML to write")->required();
  app.add_option("--report", report_dir, "folder for report.md, per-view errors and PNGs");
  app.add_option("--camera-name", camera_name, "camera_name in the YAML")->capture_default_str();
  app.add_flag("--all-terms", all_terms, "fit every distortion term of the model (no selection)");
  CLI11_PARSE(app, argc, argv);
  try {
    ct::PatternSpec pattern;
    pattern.type = ct::pattern_type_from_string(pattern_name);
    pattern.cols = cols;
    pattern.rows = rows;
    pattern.spacing_m = square;
    ct::IntrinsicsOptions options;
    options.model = rgbdt::core::distortion_model_from_string(model_name);
    options.select_distortion = !all_terms;
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(images_dir)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp") files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) {
      std::cerr << "error: no images in " << images_dir << "\n";
      return 1;
    }
    // Make the output folder now: finding out after minutes of detection that it cannot be
    // written would lose the work.
    if (const fs::path parent = fs::path(out).parent_path(); !parent.empty()) {
      std::error_code ec;
      fs::create_directories(parent, ec);
      if (ec) {
        std::cerr << "error: cannot create the folder of --out " << out << ": " << ec.message() << "\n";
        return 1;
      }
    }
    std::vector<cv::Mat> images;
    std::vector<ct::PatternDetection> det;
    std::vector<std::string> names;
    cv::Size size;
    int plain = 0;
    std::vector<std::vector<cv::Point2f>> plain_points;
    for (const auto& file : files) {
      cv::Mat img = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
      names.push_back(file.filename().string());
      ct::PatternDetection d;
      if (img.empty()) {
        d.reason = "cannot read " + file.string();
      } else if (!size.empty() && img.size() != size) {
        d.reason = "size " + std::to_string(img.cols) + "x" + std::to_string(img.rows) + " differs from the first image's " +
                   std::to_string(size.width) + "x" + std::to_string(size.height);
      } else {
        size = img.size();
        d = ct::detect_pattern(img, pattern);
        // Baseline: plain OpenCV on the image as stored (8-bit view of it).
        if (pattern.type == ct::PatternType::kCheckerboard && img.depth() == CV_8U) {
          std::vector<cv::Point2f> p;
          cv::Mat grey = img;
          if (img.channels() == 3) cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
          if (cv::findChessboardCorners(grey, cv::Size(cols, rows), p)) {
            ++plain;
            plain_points.push_back(p);
          }
        }
      }
      std::cout << file.filename().string() << ": " << (d.ok ? "found (" + d.method + ")" : d.reason) << "\n";
      images.push_back(img);
      det.push_back(d);
    }
    const auto result = ct::calibrate_intrinsics(det, names, size, pattern, options);
    std::string baseline;
    if (pattern.type == ct::PatternType::kCheckerboard) {
      std::ostringstream s;
      s << "findChessboardCorners found " << plain << "/" << files.size();
      if (plain >= 3) {
        std::vector<std::vector<cv::Point3f>> obj(plain_points.size(), pattern.object_points());
        cv::Mat K, D;
        std::vector<cv::Mat> rv, tv;
        const double rms = cv::calibrateCamera(obj, plain_points, size, K, D, rv, tv);
        s << ", calibrateCamera (default flags) RMS " << rms << " px, fx " << K.at<double>(0, 0) << ", fy " << K.at<double>(1, 1);
      }
      baseline = s.str();
    }
    int found = 0;
    for (const auto& d : det) found += d.ok ? 1 : 0;
    std::cout << "detected " << found << "/" << files.size() << " views";
    if (!baseline.empty()) std::cout << " (baseline: " << baseline << ")";
    std::cout << "\n";
    if (!result.ok) {
      std::cerr << "error: calibration failed: " << result.reason << "\n";
      return 1;
    }
    auto intrinsics = result.intrinsics;
    intrinsics.camera_name = camera_name;
    rgbdt::core::write_camera_info(out, intrinsics);
    std::cout << std::setprecision(6) << "RMS " << result.rms_px << " px, terms: " << result.distortion_terms
              << ", coverage " << result.coverage * 100 << " %\n";
    for (std::size_t k = 0; k < result.parameters.size(); ++k) {
      std::cout << "  " << result.parameter_names[k] << " = " << result.parameters[k] << " +- " << result.std_devs[k] << "\n";
    }
    for (const auto& v : result.views) {
      if (!v.used && !v.reason.empty()) std::cout << "  rejected " << v.name << ": " << v.reason << "\n";
    }
    if (!report_dir.empty()) {
      write_report(report_dir, result, images, det, baseline);
      std::cout << "report: " << (fs::path(report_dir) / "report.md").string() << "\n";
    }
    std::cout << "wrote " << out << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
