// Replays the libFuzzer regression corpus (modules/cloud/fuzz/corpus) through the same
// target body, so every input that once mattered is checked in every build. Files named
// valid_* must load; every other file (crash_*, alloc_*, bad_*, wrong_*) must be refused
// with an error naming the file, by every reader.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "../fuzz/targets.hpp"

namespace rgbdt::cloud {
namespace {

namespace fs = std::filesystem;

TEST(CloudFuzzCorpus, CloudInputsAreLoadedOrRefusedAsNamed) {
  const fs::path dir = fs::path(RGBDT_SOURCE_DIR) / "modules/cloud/fuzz/corpus";
  std::map<std::string, std::vector<std::uint8_t>> files;
  if (fs::exists(dir)) {
    for (const auto& e : fs::directory_iterator(dir)) {
      std::ifstream in(e.path(), std::ios::binary);
      files[e.path().filename().string()] = {std::istreambuf_iterator<char>(in), {}};
    }
  }
  ASSERT_GE(files.size(), 15u) << "corpus missing under " << dir;
  int valid = 0;
  for (const auto& [name, bytes] : files) {
    const int accepted = fuzz::cloud_input(bytes.data(), bytes.size());
    if (name.rfind("valid_", 0) == 0) {
      ++valid;
      // Its own reader and load_cloud accept it; the other format's reader refuses it.
      EXPECT_EQ(accepted, 2) << name;
    } else if (name.find('_') != std::string::npos && name.find('.') != std::string::npos &&
               name.size() < 48) {
      EXPECT_EQ(accepted, 0) << name;
    }
    // Other names are inputs libFuzzer found: they must only not crash.
  }
  EXPECT_GE(valid, 7);
}

}  // namespace
}  // namespace rgbdt::cloud
