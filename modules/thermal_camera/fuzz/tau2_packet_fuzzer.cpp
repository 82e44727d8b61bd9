// libFuzzer target for the Tau2 packet parser, the strict decoder and the emulator.
// Build (separate build folder, clang):
//   CC=clang-14 CXX=clang++-14 cmake -S . -B build-fuzz -G Ninja -DRGBDT_BUILD_FUZZERS=ON
//   cmake --build build-fuzz --target tau2_packet_fuzzer
//   build-fuzz/bin/tau2_packet_fuzzer -max_total_time=180 CORPUS_DIR
//   modules/thermal_camera/fuzz/corpus
#include <cstdio>
#include <cstdlib>

#include "tau2_packet_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string broken = rgbdt::thermal_camera::fuzz::check_tau2_input(data, size);
  if (!broken.empty()) {
    std::fprintf(stderr, "property violated: %s\n", broken.c_str());
    std::abort();
  }
  return 0;
}
