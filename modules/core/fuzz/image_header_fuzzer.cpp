// libFuzzer target: arbitrary bytes into the PNG and JPEG header reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::image_header_input(data, size);
  return 0;
}
