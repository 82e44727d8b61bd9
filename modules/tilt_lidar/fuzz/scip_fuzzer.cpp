// libFuzzer target: arbitrary bytes into the SCIP 2.0 response parser and scan decoder.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::tilt_lidar::fuzz::scip_input(data, size);
  return 0;
}
