#pragma once
// Still intervals of a calibration recording: the board is held still while consecutive
// camera frames differ little.
#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace rgbdt::import {

/// How much consecutive frames differ: the mean absolute difference of grey levels on a
/// downscaled copy (noise and small vibrations average out), in 8-bit grey levels. 16-bit
/// frames (thermal counts) are scaled to 0..255 by the first frame's range, so that one
/// threshold fits both.
class FrameDifference {
 public:
  /// `width_px`: the width frames are downscaled to before comparing.
  explicit FrameDifference(int width_px = 160);

  /// The difference between `image` and the frame added before it; nullopt for the first.
  std::optional<double> add(const cv::Mat& image);

 private:
  cv::Mat grey(const cv::Mat& image);

  int width_px_;
  double scale16_ = 0.0;  // 255 / range of the first 16-bit frame
  cv::Mat previous_;
};

/// One run of frames, each differing from the one before it by less than the threshold.
struct FrameRun {
  std::size_t first = 0;  ///< index of the run's first frame
  std::size_t last = 0;   ///< index of its last frame
  std::size_t frames() const { return last - first + 1; }
};

/// Splits frames into runs: frame i continues the run of frame i - 1 when differences[i]
/// (its difference to frame i - 1) is below `threshold`. differences[0] is ignored. Every
/// frame is in exactly one run.
std::vector<FrameRun> split_runs(const std::vector<double>& differences, double threshold);

}  // namespace rgbdt::import
