// rgbdt::tilt_lidar alone: a Hokuyo SCIP scan encoded and decoded.
#include <rgbdt/tilt_lidar/scip.hpp>

#include <iostream>

int main() {
  using namespace rgbdt::tilt_lidar;
  scip::ScanFrame frame;
  frame.timestamp_ms = 123456;
  for (int k = 0; k < 1081; ++k) frame.ranges_mm.push_back(1000 + 7 * k);
  std::string why;
  const auto decoded = scip::decode_scan_lines(scip::encode_scan_lines(frame), 1081, false, &why);
  std::cout << "consumer tilt_lidar: " << (decoded ? decoded->ranges_mm.size() : 0)
            << " ranges decoded" << why << "\n";
  return decoded && decoded->ranges_mm == frame.ranges_mm &&
                 decoded->timestamp_ms == frame.timestamp_ms
             ? 0
             : 1;
}
