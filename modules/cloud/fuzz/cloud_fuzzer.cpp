// libFuzzer target: arbitrary bytes as a PCD and as a PLY file through the checked readers.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::cloud::fuzz::cloud_input(data, size);
  return 0;
}
