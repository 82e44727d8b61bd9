// Replays the libFuzzer regression corpus (modules/tilt_lidar/fuzz/corpus) through the
// same target bodies, so every input that once mattered is checked in every build.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "../fuzz/targets.hpp"

namespace rgbdt::tilt_lidar {
namespace {

namespace fs = std::filesystem;

std::map<std::string, std::vector<std::uint8_t>> corpus(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_SOURCE_DIR) / "modules/tilt_lidar/fuzz/corpus" / name;
  std::map<std::string, std::vector<std::uint8_t>> out;
  if (!fs::exists(dir)) return out;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    out[e.path().filename().string()] = {std::istreambuf_iterator<char>(in), {}};
  }
  return out;
}

TEST(FuzzCorpus, ScipInputsParseWithoutCrashing) {
  const auto files = corpus("scip");
  ASSERT_GE(files.size(), 5u) << "corpus missing under modules/tilt_lidar/fuzz/corpus/scip";
  for (const auto& [name, bytes] : files) fuzz::scip_input(bytes.data(), bytes.size());
  // The hand-written seeds: valid responses are accepted, the corrupt one is not.
  EXPECT_EQ(fuzz::scip_input(files.at("md_scan").data(), files.at("md_scan").size()), 1);
  EXPECT_EQ(fuzz::scip_input(files.at("pp").data(), files.at("pp").size()), 1);
  EXPECT_EQ(fuzz::scip_input(files.at("bad_checksum").data(), files.at("bad_checksum").size()), 0);
}

TEST(FuzzCorpus, DynamixelInputsParseWithoutCrashing) {
  const auto files = corpus("dynamixel");
  ASSERT_GE(files.size(), 6u) << "corpus missing under modules/tilt_lidar/fuzz/corpus/dynamixel";
  for (const auto& [name, bytes] : files) fuzz::dynamixel_input(bytes.data(), bytes.size());
  const auto& two = files.at("two_with_garbage");
  EXPECT_EQ(fuzz::dynamixel_input(two.data(), two.size()), 2);
  const auto& stuffed = files.at("write_stuffed");
  EXPECT_EQ(fuzz::dynamixel_input(stuffed.data(), stuffed.size()), 1);
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
