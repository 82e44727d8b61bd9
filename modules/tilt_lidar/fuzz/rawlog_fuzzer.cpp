// libFuzzer target: arbitrary bytes as an MRPT rawlog file (plain or gzip) into the bounded
// rawlog reader and the replay into the assembler.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::tilt_lidar::fuzz::rawlog_input(data, size);
  return 0;
}
