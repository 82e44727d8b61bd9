// rgbdt::error_model alone: the paper's Eq. (9) number for the RGB camera.
#include <rgbdt/error_model/paper_analysis.hpp>

#include <cmath>
#include <iostream>

int main() {
  const double z = rgbdt::error_model::lidar_noise_depth_m(1335.054, 0.02);
  std::cout << "consumer error_model: Eq. (9) depth " << z << " m (paper: 4.30 m)\n";
  return std::abs(z - 4.303249) < 1e-5 ? 0 : 1;
}
