// libFuzzer target: arbitrary bytes into the camera_info reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::camera_info_input(data, size);
  return 0;
}
