// libFuzzer target: arbitrary bytes as a bag file (MCAP through the vendored mcap library,
// sqlite3), read through open_bag and decoded.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::bag::fuzz::mcap_input(data, size);
  return 0;
}
