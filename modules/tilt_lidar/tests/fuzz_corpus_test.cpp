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

// Rawlogs (seeds from fuzz/make_rawlog_seeds.py plus the fuzzer's finds): the valid ones
// read whole, the hostile ones (forged counts, gzip garbage, empty) read nothing and end
// in an error, never in a crash or a huge allocation.
TEST(FuzzCorpus, RawlogInputsReadWithoutCrashing) {
  const auto files = corpus("rawlog");
  ASSERT_GE(files.size(), 10u) << "corpus missing under modules/tilt_lidar/fuzz/corpus/rawlog";
  for (const auto& [name, bytes] : files) fuzz::rawlog_input(bytes.data(), bytes.size());
  auto read = [&](const std::string& name) {
    const auto& b = files.at(name);
    return fuzz::rawlog_input(b.data(), b.size());
  };
  EXPECT_EQ(read("valid_scans_encoder"), 4);
  EXPECT_EQ(read("valid_scans_encoder_gz"), 4);
  EXPECT_EQ(read("valid_sensory_frame"), 2);
  EXPECT_EQ(read("nan_ranges"), 2);
  for (const char* hostile : {"forged_beam_count", "forged_beam_count_gz", "count_beyond_file", "gzip_garbage", "empty",
                              "frame_huge_count", "daq_huge_vector", "pose_huge_matrix", "label_huge", "top_level_map",
                              "scan_bool_16"}) {
    EXPECT_EQ(read(hostile), 0) << hostile;
  }
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
