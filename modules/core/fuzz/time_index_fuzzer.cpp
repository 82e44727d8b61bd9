// libFuzzer target: arbitrary bytes into the time_index reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::time_index_input(data, size);
  return 0;
}
