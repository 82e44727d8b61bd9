#pragma once
/// \file
/// Writes camera frames as PNG files with a time index (design.md: "time_s,file" CSV,
/// core::write_time_index), so that a recording stopped at any moment (Ctrl-C, camera
/// unplugged, process killed) holds only whole images and an index that lists them.
///
/// Layout of `out_dir`: 000000.png, 000001.png, ... and index.csv. 16-bit images
/// (Mono10..Mono16, thermal raw counts) are written as 16-bit grey PNG, Mono8 as 8-bit
/// grey, Bayer as 8-bit BGR after demosaicing (or raw with demosaic_bayer = false).
#include <cstddef>
#include <string>
#include <vector>

#include "rgbdt/core/time_index.hpp"
#include "rgbdt/thermal_camera/genicam_camera.hpp"

namespace rgbdt::thermal_camera {

struct FrameRecorderOptions {
  std::string out_dir;         ///< created if missing; must not already hold an index.csv
  bool demosaic_bayer = true;  ///< Bayer frames: write BGR (true) or the raw mosaic (false)
  /// 0..9. 640x512 16-bit frames per CPU-second (thermal_camera_bench): ~140 at 0, ~70 at
  /// 1, ~45 at 3, ~15 at 6 (loaded 2-core host); 1 keeps up with a Tau2 at 30 fps.
  int png_compression = 1;
  /// index.csv is rewritten (atomically) at most this often, and on flush/destruction.
  double index_flush_interval_s = 1.0;
  std::string validate() const;
};

class FrameRecorder {
 public:
  /// Throws std::invalid_argument for bad options and rgbdt::core::Error naming the folder
  /// when it cannot be created or already holds a recording.
  explicit FrameRecorder(const FrameRecorderOptions& options);
  /// Flushes the index (errors are logged, not thrown).
  ~FrameRecorder();
  FrameRecorder(const FrameRecorder&) = delete;
  FrameRecorder& operator=(const FrameRecorder&) = delete;

  /// Writes the frame as the next PNG (to a temporary name, then renamed, so a reader
  /// never sees a partial file) and adds it to the index at `time_s`. Returns the path.
  /// Throws rgbdt::core::Error naming the file on a write failure (disk full, ...).
  std::string write(const Frame& frame, double time_s);
  /// Rewrites index.csv now (temporary file + rename).
  void flush_index();

  size_t frames_written() const { return entries_.size(); }
  const std::string& index_path() const { return index_path_; }

 private:
  FrameRecorderOptions options_;
  std::string index_path_;
  std::vector<core::TimedFile> entries_;
  double last_flush_s_ = -1e300;
  bool dirty_ = false;
};

}  // namespace rgbdt::thermal_camera
