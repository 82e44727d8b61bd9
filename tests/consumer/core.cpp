// rgbdt::core alone: a transform through the extrinsics parametrisation and back.
#include <rgbdt/core/transform.hpp>

#include <cmath>
#include <iostream>

int main() {
  using namespace rgbdt;
  const Eigen::Isometry3d T =
      core::make_transform(core::rotation_from_rpy(0.1, -0.2, 0.3), {0.1, -0.05, 0.02});
  const Eigen::Isometry3d back = core::from_vector6(core::to_vector6(T));
  const double dr = core::rotation_error_rad(back, T), dt = core::translation_error_m(back, T);
  std::cout << "consumer core: to_vector6 round trip within " << dr << " rad, " << dt << " m\n";
  return dr < 1e-12 && dt < 1e-12 ? 0 : 1;
}
