// libFuzzer target: arbitrary bytes into the tilt_rig reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::tilt_rig_input(data, size);
  return 0;
}
