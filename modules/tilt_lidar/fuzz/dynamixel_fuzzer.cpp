// libFuzzer target: arbitrary bytes into the Dynamixel Protocol 2.0 packet parser.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::tilt_lidar::fuzz::dynamixel_input(data, size);
  return 0;
}
