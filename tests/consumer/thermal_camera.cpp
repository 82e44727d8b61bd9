// rgbdt::thermal_camera alone: a Tau2 TLinear count to kelvin and back.
#include <rgbdt/thermal_camera/radiometry.hpp>

#include <cmath>
#include <iostream>

int main() {
  using namespace rgbdt;
  const thermal_camera::Radiometry r(thermal_camera::LinearRadiometry{0.04, 0.0});
  const double k = r.kelvin(7500);
  std::cout << "consumer thermal_camera: " << r.describe() << ": 7500 counts = " << k << " K\n";
  return std::abs(k - 300.0) < 1e-9 && std::abs(r.counts(k) - 7500.0) < 1e-6 ? 0 : 1;
}
