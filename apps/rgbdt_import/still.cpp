#include "still.hpp"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace rgbdt::import {

FrameDifference::FrameDifference(int width_px) : width_px_(std::max(8, width_px)) {}

cv::Mat FrameDifference::grey(const cv::Mat& image) {
  cv::Mat one;
  if (image.channels() == 3) {
    cv::cvtColor(image, one, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, one, cv::COLOR_BGRA2GRAY);
  } else {
    one = image;
  }
  cv::Mat f;
  if (one.depth() == CV_16U) {
    if (scale16_ == 0.0) {
      double lo = 0, hi = 0;
      cv::minMaxLoc(one, &lo, &hi);
      scale16_ = 255.0 / std::max(1.0, hi - lo);
    }
    one.convertTo(f, CV_32F, scale16_);
  } else {
    one.convertTo(f, CV_32F);
  }
  const int width = std::min(width_px_, f.cols);
  const int height = std::max(1, static_cast<int>(double(f.rows) * width / f.cols + 0.5));
  cv::Mat small;
  cv::resize(f, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  return small;
}

std::optional<double> FrameDifference::add(const cv::Mat& image) {
  cv::Mat small = grey(image);
  std::optional<double> difference;
  if (!previous_.empty()) {
    if (previous_.size() != small.size()) {
      difference = 255.0;  // a frame of another size is a different view
    } else {
      cv::Mat d;
      cv::absdiff(small, previous_, d);
      difference = cv::mean(d)[0];
    }
  }
  previous_ = small;
  return difference;
}

std::vector<FrameRun> split_runs(const std::vector<double>& differences, double threshold) {
  std::vector<FrameRun> runs;
  for (std::size_t i = 0; i < differences.size(); ++i) {
    if (i == 0 || !(differences[i] < threshold)) {
      runs.push_back({i, i});
    } else {
      runs.back().last = i;
    }
  }
  return runs;
}

}  // namespace rgbdt::import
