#include "rgbdt/thermal_camera/frame_recorder.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::thermal_camera {
namespace fs = std::filesystem;

namespace {

double monotonic_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Writes bytes to `path` through a temporary sibling and a rename, which is atomic on
// POSIX file systems: the final name only ever holds a whole file.
void write_atomically(const fs::path& path, const std::vector<uchar>& bytes) {
  const fs::path tmp = path.parent_path() / ("." + path.filename().string() + ".tmp");
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw core::Error(tmp.string(), "cannot open for writing");
    f.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
    f.close();
    if (!f) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw core::Error(tmp.string(), "write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec)
    throw core::Error(path.string(),
                      "cannot rename the temporary file into place: " + ec.message());
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
  write_atomically(path, png);
  entries_.push_back({time_s, path.string()});
  dirty_ = true;
  if (monotonic_s() - last_flush_s_ >= options_.index_flush_interval_s) flush_index();
  return path.string();
}

void FrameRecorder::flush_index() {
  const fs::path final_path(index_path_);
  const fs::path tmp = final_path.parent_path() / ".index.csv.tmp";
  core::write_time_index(tmp.string(), entries_);
  std::error_code ec;
  fs::rename(tmp, final_path, ec);
  if (ec)
    throw core::Error(index_path_, "cannot rename the temporary index into place: " + ec.message());
  last_flush_s_ = monotonic_s();
  dirty_ = false;
}

}  // namespace rgbdt::thermal_camera
