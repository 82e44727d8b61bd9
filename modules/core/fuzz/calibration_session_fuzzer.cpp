// libFuzzer target: arbitrary bytes into the calibration_session reader (see targets.hpp).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::core::fuzz::calibration_session_input(data, size);
  return 0;
}
