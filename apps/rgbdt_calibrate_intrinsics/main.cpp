// rgbdt_calibrate_intrinsics: intrinsic calibration of an RGB or thermal camera from a
// folder of images of a checkerboard or circle grid (paper Sec. 3.1).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app_config.hpp"
#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/intrinsics.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/image_header.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/output.hpp"

namespace fs = std::filesystem;
namespace ct = rgbdt::calib_targets;

namespace {

cv::Mat to_bgr(const cv::Mat& image) {
  cv::Mat f = ct::normalise_image(image, 0.5, 99.5), u8, bgr;
  f.convertTo(u8, CV_8U, 255.0);
  cv::cvtColor(u8, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

/// Writes an image through a temporary file; throws naming the file when it fails.
void write_png(const fs::path& path, const cv::Mat& image) {
  rgbdt::core::TempOutput out(path.string());
  if (!cv::imwrite(out.temp_path(), image)) throw rgbdt::core::Error(path.string(), "cannot write the PNG");
  out.commit();
}

/// Why the estimate must not be used, or an empty string when it passes every check.
std::string verdict_problem(const ct::IntrinsicsResult& r, cv::Size size, double max_rms_px) {
  std::ostringstream os;
  const auto& k = r.intrinsics;
  bool finite = std::isfinite(r.rms_px);
  for (double p : r.parameters) finite = finite && std::isfinite(p);
  if (!finite) return "the estimate is not finite";
  if (!(k.fx > 0 && k.fy > 0)) {
    os << "focal lengths fx = " << k.fx << ", fy = " << k.fy << " px, expected > 0";
  } else if (!(k.cx >= 0 && k.cx <= size.width && k.cy >= 0 && k.cy <= size.height)) {
    os << "principal point (" << k.cx << ", " << k.cy << ") px outside the " << size.width << "x" << size.height
       << " image";
  } else if (r.rms_px > max_rms_px) {
    os << "RMS reprojection error " << r.rms_px << " px above --max-rms " << max_rms_px << " px";
  } else if (const std::string why = k.validate(); !why.empty()) {
    os << why;
  }
  return os.str();
}

void write_report(const fs::path& dir, const ct::IntrinsicsResult& r, const std::vector<cv::Mat>& images,
                  const std::vector<ct::PatternDetection>& det, const std::string& baseline,
                  const std::vector<std::string>& skipped, const std::string& verdict,
                  const std::string& config_yaml) {
  fs::create_directories(dir / "views");
  std::ostringstream md;
  md << "# Intrinsic calibration\n\n";
  if (!verdict.empty()) md << "**FAILED: " << verdict << ". The camera_info was not written.**\n\n";
  md << "- model: " << rgbdt::core::to_string(r.intrinsics.model) << ", estimated terms: " << r.distortion_terms << "\n";
  md << "- RMS reprojection error: " << r.rms_px << " px\n";
  md << "- coverage (8x8 grid cells with points): " << r.coverage * 100.0 << " %\n";
  int used = 0;
  for (const auto& v : r.views) used += v.used ? 1 : 0;
  md << "- views used: " << used << " of " << r.views.size() << "\n";
  if (!baseline.empty()) md << "- baseline (plain OpenCV): " << baseline << "\n";
  if (!skipped.empty()) {
    md << "\n## Images not used\n\n";
    for (const auto& s : skipped) md << "- " << s << "\n";
  }
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
  std::ostringstream csv;
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
    write_png(dir / "views" / (fs::path(view.name).stem().string() + "_corners.png"), vis);
    if (!view.used) continue;
    for (std::size_t k = 0; k < view.points.size(); ++k) {
      cv::circle(coverage, view.points[k], 3, {0, 255, 0}, -1);
      const cv::Point2f d = view.points[k] - view.reprojected[k];
      cv::circle(residuals, cv::Point2f(300.f + 100.f * d.x, 300.f + 100.f * d.y), 1, {200, 0, 0}, -1);
    }
  }
  cv::putText(residuals, "residuals: 100 px per px, circle = 1 px", {10, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0});
  if (!coverage.empty()) write_png(dir / "coverage.png", coverage);
  write_png(dir / "residuals.png", residuals);
  rgbdt::core::write_file_atomic((dir / "per_view_errors.csv").string(), csv.str());
  md << "\nImages: `coverage.png`, `residuals.png`, `views/*_corners.png`; per-view errors in `per_view_errors.csv`.\n";
  md << "\n## Configuration\n\nThe options this run used (`--config` reads this block back):\n\n```yaml\n"
     << config_yaml << "```\n";
  // Last: report.md marks a complete report.
  rgbdt::core::write_file_atomic((dir / "report.md").string(), md.str());
}

}  // namespace

/// The images of `dir` (png, jpg, tif, bmp; any case), in name order.
std::vector<fs::path> list_images(const std::string& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

/// One image read and searched for the pattern; the reason when it cannot be used.
struct ImageDetection {
  cv::Mat image;
  ct::PatternDetection detection;
};

ImageDetection detect_in_file(const fs::path& file, const ct::PatternSpec& pattern) {
  // PNG and JPEG headers are checked before decoding, so a file claiming a huge size is
  // refused before OpenCV allocates for it (other formats go to OpenCV directly).
  std::string header_problem;
  const std::string ext = fs::path(file).extension().string();
  if (ext == ".png" || ext == ".PNG" || ext == ".jpg" || ext == ".jpeg" || ext == ".JPG" || ext == ".JPEG") {
    try {
      (void)rgbdt::core::read_image_header(file.string());
    } catch (const std::exception& e) {
      header_problem = e.what();
    }
  }
  ImageDetection r;
  if (header_problem.empty()) r.image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (!header_problem.empty()) {
    r.detection.reason = header_problem;
  } else if (r.image.empty()) {
    r.detection.reason = "cannot read " + file.string() + " (expected an image: png, jpg, tif, bmp)";
  } else {
    r.detection = ct::detect_pattern(r.image, pattern);
  }
  return r;
}

/// The views of one image size: that of the largest group of images where the pattern was
/// found (a stray image of another size does not decide it). The others are named in
/// `skipped` with their size.
struct SizeGroup {
  cv::Size size;  ///< empty when the pattern was found in no image
  std::vector<cv::Mat> images;
  std::vector<ct::PatternDetection> detections;
  std::vector<std::string> names, skipped;
};

SizeGroup largest_size_group(const std::vector<fs::path>& files, const std::vector<ImageDetection>& all) {
  std::map<std::pair<int, int>, int> groups;
  for (const auto& d : all)
    if (d.detection.ok) ++groups[{d.image.cols, d.image.rows}];
  SizeGroup g;
  int best = 0;
  for (const auto& [wh, count] : groups)
    if (count > best) {
      best = count;
      g.size = cv::Size(wh.first, wh.second);
    }
  for (std::size_t k = 0; k < files.size(); ++k) {
    const std::string name = files[k].filename().string();
    const cv::Mat& img = all[k].image;
    if (!img.empty() && !g.size.empty() && img.size() != g.size) {
      const std::string why = "size " + std::to_string(img.cols) + "x" + std::to_string(img.rows) +
                              " differs from the " + std::to_string(g.size.width) + "x" + std::to_string(g.size.height) +
                              " of the " + std::to_string(best) + " image(s) with the pattern";
      std::cout << "  skipped " << name << ": " << why << "\n";
      g.skipped.push_back(name + ": " + why);
      continue;
    }
    g.images.push_back(img);
    g.detections.push_back(all[k].detection);
    g.names.push_back(name);
  }
  return g;
}

/// Plain OpenCV on the images as stored (8-bit ones only): findChessboardCorners and
/// calibrateCamera with default flags, as one line for the report.
std::string plain_opencv_baseline(const std::vector<cv::Mat>& images, const ct::PatternSpec& pattern, cv::Size size) {
  int plain = 0;
  std::vector<std::vector<cv::Point2f>> plain_points;
  for (const cv::Mat& img : images) {
    if (img.depth() != CV_8U) continue;
    std::vector<cv::Point2f> p;
    cv::Mat grey = img;
    if (img.channels() == 3) cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
    if (cv::findChessboardCorners(grey, cv::Size(pattern.cols, pattern.rows), p)) {
      ++plain;
      plain_points.push_back(p);
    }
  }
  std::ostringstream s;
  s << "findChessboardCorners found " << plain << "/" << images.size();
  if (plain >= 3) {
    std::vector<std::vector<cv::Point3f>> obj(plain_points.size(), pattern.object_points());
    cv::Mat K, D;
    std::vector<cv::Mat> rv, tv;
    const double rms = cv::calibrateCamera(obj, plain_points, size, K, D, rv, tv);
    s << ", calibrateCamera (default flags) RMS " << rms << " px, fx " << K.at<double>(0, 0) << ", fy " << K.at<double>(1, 1);
  }
  return s.str();
}

void print_result(const ct::IntrinsicsResult& result) {
  std::cout << std::setprecision(6) << "RMS " << result.rms_px << " px, terms: " << result.distortion_terms
            << ", coverage " << result.coverage * 100 << " %\n";
  for (std::size_t k = 0; k < result.parameters.size(); ++k) {
    std::cout << "  " << result.parameter_names[k] << " = " << result.parameters[k] << " +- " << result.std_devs[k] << "\n";
  }
  for (const auto& v : result.views) {
    if (!v.used && !v.reason.empty()) std::cout << "  rejected " << v.name << ": " << v.reason << "\n";
  }
}

int main(int argc, char** argv) {
  CLI::App app{
      "Intrinsic calibration of an RGB or thermal camera from images of a checkerboard or a circle grid.\n"
      "16-bit and low-contrast thermal images are normalised by percentiles; both polarities are tried\n"
      "(black squares may be warm); corners are refined on the normalised data; unreliable views are\n"
      "rejected with the reason; the distortion terms are chosen by cross-validation over views.\n"
      "The pattern is searched on images of at most 1000 px (larger ones are downscaled) and refined\n"
      "at full resolution. Images of another size than the largest group of images with the pattern\n"
      "are skipped and named. An estimate that fails its checks (finite, principal point inside the\n"
      "image, RMS within --max-rms) is reported as failed and not written (exit 2).\n"
      "Writes a ROS camera_info YAML and, with --report, report.md, per-view errors and PNGs."};
  rgbdt::apps::add_config_option(app, argc, argv);
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
  bool with_baseline = false;
  double max_rms = 1.0;
  app.add_option("--max-rms", max_rms, "largest acceptable RMS reprojection error of the estimate [px]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_flag("--baseline", with_baseline,
               "also run plain OpenCV (findChessboardCorners + calibrateCamera on the full-size images) "
               "for comparison; unbounded: minutes per large image without the pattern");
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
    const std::vector<fs::path> files = list_images(images_dir);
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
    if (!report_dir.empty()) rgbdt::core::remove_stale_output((fs::path(report_dir) / "report.md").string());
    rgbdt::core::install_interrupt_handler();
    // Detection on every image; the sizes are grouped afterwards.
    std::vector<ImageDetection> all;
    for (const auto& file : files) {
      if (rgbdt::core::interrupted()) {
        std::cerr << "interrupted after " << all.size() << " of " << files.size() << " images; nothing was written\n";
        return 130;
      }
      all.push_back(detect_in_file(file, pattern));
      const ct::PatternDetection& d = all.back().detection;
      std::cout << file.filename().string() << ": " << (d.ok ? "found (" + d.method + ")" : d.reason) << "\n";
      std::cout.flush();
    }
    SizeGroup group = largest_size_group(files, all);
    all.clear();
    const cv::Size size = group.size;
    const std::vector<cv::Mat>& images = group.images;
    const std::vector<ct::PatternDetection>& det = group.detections;
    const std::vector<std::string>& skipped = group.skipped;
    if (size.empty()) {
      std::cerr << "error: the " << pattern.cols << "x" << pattern.rows << " " << pattern_name
                << " pattern was found in none of the " << files.size() << " images of " << images_dir << "\n";
      return 1;
    }
    const auto result = ct::calibrate_intrinsics(det, group.names, size, pattern, options);
    std::string baseline;
    if (with_baseline && pattern.type == ct::PatternType::kCheckerboard) {
      baseline = plain_opencv_baseline(images, pattern, size);
    }
    int found = 0;
    for (const auto& d : det) found += d.ok ? 1 : 0;
    std::cout << "detected " << found << "/" << files.size() << " views";
    if (!skipped.empty()) std::cout << ", " << skipped.size() << " image(s) of another size skipped";
    if (!baseline.empty()) std::cout << " (baseline: " << baseline << ")";
    std::cout << "\n";
    if (!result.ok) {
      std::cerr << "error: calibration failed: " << result.reason << "\n";
      return 1;
    }
    const std::string verdict = verdict_problem(result, size, max_rms);
    auto intrinsics = result.intrinsics;
    intrinsics.camera_name = camera_name;
    print_result(result);
    if (rgbdt::core::interrupted()) {
      std::cerr << "interrupted before writing; nothing was written\n";
      return 130;
    }
    if (!report_dir.empty()) {
      write_report(report_dir, result, images, det, baseline, skipped, verdict, rgbdt::apps::effective_config_yaml(app));
      std::cout << "report: " << (fs::path(report_dir) / "report.md").string() << "\n";
    }
    if (!verdict.empty()) {
      std::cerr << "error: calibration failed its checks: " << verdict << "; " << out << " was not written\n";
      return 2;
    }
    rgbdt::core::write_file_atomic(out, rgbdt::core::format_camera_info(intrinsics));
    std::cout << "wrote " << out << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
