// libFuzzer target: arbitrary bytes into the CDR and ROS 1 message decoders and the
// PointCloud2 point extraction (the first byte picks serialization and type).
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rgbdt::bag::fuzz::message_input(data, size);
  return 0;
}
