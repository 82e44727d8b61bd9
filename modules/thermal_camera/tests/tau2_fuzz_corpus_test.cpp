// Replays the kept libFuzzer corpus (modules/thermal_camera/fuzz/corpus) through the same
// property checks as the fuzzer, so every normal build re-checks what fuzzing found.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "../fuzz/tau2_packet_checks.hpp"

namespace fs = std::filesystem;

TEST(Tau2FuzzCorpus, EveryKeptInputSatisfiesTheParserProperties) {
  const fs::path corpus = fs::path(RGBDT_SOURCE_DIR) / "modules/thermal_camera/fuzz/corpus";
  ASSERT_TRUE(fs::is_directory(corpus)) << "missing corpus folder " << corpus;
  size_t inputs = 0, packets = 0;
  for (const auto& entry : fs::directory_iterator(corpus)) {
    if (!entry.is_regular_file()) continue;
    std::ifstream f(entry.path(), std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(f)),
                                     std::istreambuf_iterator<char>());
    const std::string broken =
        rgbdt::thermal_camera::fuzz::check_tau2_input(bytes.data(), bytes.size());
    EXPECT_TRUE(broken.empty()) << entry.path() << ": " << broken;
    ++inputs;
    packets += rgbdt::thermal_camera::tau2::parse(bytes.data(), bytes.size()).kind ==
               rgbdt::thermal_camera::tau2::ParseResult::Kind::kPacket;
  }
  // The corpus must exercise both valid packets and rejected ones.
  EXPECT_GE(inputs, 10u);
  EXPECT_GE(packets, 3u);
  EXPECT_LT(packets, inputs);
}
