#include "rgbdt/thermal_camera/frame_recorder.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/time_index.hpp"

namespace rgbdt::thermal_camera {
namespace fs = std::filesystem;

namespace {

double monotonic_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string FrameRecorderOptions::validate() const {
  if (out_dir.empty()) return "out_dir is empty";
  if (png_compression < 0 || png_compression > 9) {
    return "png_compression = " + std::to_string(png_compression) + ", expected 0..9";
  }
  if (!(index_flush_interval_s >= 0.0)) return "index_flush_interval_s must be >= 0";
  return {};
}

FrameRecorder::FrameRecorder(const FrameRecorderOptions& options) : options_(options) {
  if (const auto why = options.validate(); !why.empty()) {
    throw std::invalid_argument("FrameRecorderOptions: " + why);
  }
  std::error_code ec;
  fs::create_directories(options.out_dir, ec);
  if (ec) throw core::Error(options.out_dir, "cannot create the output folder: " + ec.message());
  index_path_ = (fs::path(options.out_dir) / "index.csv").string();
  if (fs::exists(index_path_)) {
    throw core::Error(index_path_, "already exists; choose an empty folder for a new recording");
  }
  flush_index();  // an empty index marks the folder as a recording from the start
}

FrameRecorder::~FrameRecorder() {
  try {
    if (dirty_) flush_index();
  } catch (const std::exception& e) {
    core::log_error("FrameRecorder: ", e.what());
  }
}

std::string FrameRecorder::write(const Frame& frame, double time_s) {
  if (frame.image.empty()) throw std::invalid_argument("FrameRecorder::write: empty image");
  const cv::Mat image = options_.demosaic_bayer ? to_viewable(frame) : frame.image;
  char name[32];
  std::snprintf(name, sizeof name, "%06zu.png", entries_.size());
  const fs::path path = fs::path(options_.out_dir) / name;
  std::vector<uchar> png;
  if (!cv::imencode(".png", image, png, {cv::IMWRITE_PNG_COMPRESSION, options_.png_compression})) {
    throw core::Error(path.string(), "PNG encoding failed for a " + std::to_string(image.cols) +
                                         "x" + std::to_string(image.rows) + " image of type " +
                                         std::to_string(image.type()));
  }
  // The final name only ever holds a whole frame (a temporary sibling renamed into place).
  core::write_file_atomic(
      path.string(), std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  entries_.push_back({time_s, path.string()});
  dirty_ = true;
  if (monotonic_s() - last_flush_s_ >= options_.index_flush_interval_s) flush_index();
  return path.string();
}

void FrameRecorder::flush_index() {
  core::write_time_index(index_path_, entries_);  // atomic: a reader sees a whole index
  last_flush_s_ = monotonic_s();
  dirty_ = false;
}

}  // namespace rgbdt::thermal_camera
