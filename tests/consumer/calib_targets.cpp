// rgbdt::calib_targets alone: an 8-bit ramp normalised to [0, 1].
#include <rgbdt/calib_targets/image_target.hpp>

#include <iostream>

int main() {
  using namespace rgbdt;
  cv::Mat ramp(10, 256, CV_8UC1);
  for (int c = 0; c < 256; ++c) ramp.col(c).setTo(c);
  const cv::Mat n = calib_targets::normalise_image(ramp, 0.0, 100.0);
  double lo = 0, hi = 0;
  cv::minMaxLoc(n, &lo, &hi);
  std::cout << "consumer calib_targets: normalised to [" << lo << ", " << hi << "]\n";
  return n.type() == CV_32FC1 && lo < 0.01 && hi > 0.99 ? 0 : 1;
}
