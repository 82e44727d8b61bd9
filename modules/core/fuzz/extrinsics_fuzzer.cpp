// libFuzzer target: arbitrary bytes into the extrinsics reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::extrinsics_input(data, size);
  return 0;
}
