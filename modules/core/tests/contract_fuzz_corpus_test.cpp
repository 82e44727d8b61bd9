// Replays the libFuzzer corpora of the contract readers (modules/core/fuzz/corpus) through
// the same target bodies: every reader accepts the valid files, refuses the finding cases
// with core::Error or std::invalid_argument, and never crashes on any of them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <vector>

#include "../fuzz/targets.hpp"

namespace rgbdt::core {
namespace {

namespace fs = std::filesystem;
using Target = int (*)(const std::uint8_t*, std::size_t);

std::map<std::string, std::vector<std::uint8_t>> corpus(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_SOURCE_DIR) / "modules/core/fuzz/corpus" / name;
  std::map<std::string, std::vector<std::uint8_t>> out;
  if (!fs::exists(dir)) return out;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    out[e.path().filename().string()] = {std::istreambuf_iterator<char>(in), {}};
  }
  return out;
}

// Every file replays; files named valid* are accepted, the hand-written finding cases listed
// in `refused` are not.
void replay(const std::string& name, Target target, const std::vector<std::string>& refused) {
  const auto files = corpus(name);
  ASSERT_GE(files.size(), 4u) << "corpus missing under modules/core/fuzz/corpus/" << name;
  for (const auto& [file, bytes] : files) {
    const int accepted = target(bytes.data(), bytes.size());
    if (file.rfind("valid", 0) == 0) {
      EXPECT_EQ(accepted, 1) << name << "/" << file;
    }
  }
  for (const auto& file : refused) {
    ASSERT_TRUE(files.count(file)) << name << "/" << file;
    EXPECT_EQ(target(files.at(file).data(), files.at(file).size()), 0) << name << "/" << file;
  }
}

TEST(FuzzCorpus, CameraInfo) {
  replay("camera_info", fuzz::camera_info_input,
         {"cx_outside", "rows_negative", "duplicate_key", "matrix_wrong_type", "inf_width"});
}

TEST(FuzzCorpus, Extrinsics) {
  replay("extrinsics", fuzz::extrinsics_input, {"nan_translation", "quaternion_norm_2"});
  const auto files = corpus("extrinsics");
  EXPECT_EQ(fuzz::extrinsics_input(files.at("lidar_parent").data(), files.at("lidar_parent").size()), 1);
}

TEST(FuzzCorpus, TiltRig) {
  replay("tilt_rig", fuzz::tilt_rig_input, {"inf_period", "duplicate_motor", "self_alias", "deep_nesting"});
}

TEST(FuzzCorpus, TimeIndex) {
  replay("time_index", fuzz::time_index_input, {"time_trailing_garbage", "time_hex", "png_bytes"});
  const auto files = corpus("time_index");
  EXPECT_EQ(fuzz::time_index_input(files.at("header_only").data(), files.at("header_only").size()), 1);
}

TEST(FuzzCorpus, CalibrationSession) {
  replay("calibration_session", fuzz::calibration_session_input,
         {"radius_inf", "board_negative", "unsafe_camera_name", "duplicate_target", "seed_nan"});
}

TEST(FuzzCorpus, MappingSession) {
  replay("mapping_session", fuzz::mapping_session_input,
         {"kelvin_inf", "frames_folder", "duplicate_camera"});
  const auto files = corpus("mapping_session");
  for (const char* f : {"lidar_only", "empty_cameras"}) {
    EXPECT_EQ(fuzz::mapping_session_input(files.at(f).data(), files.at(f).size()), 1) << f;
  }
}

TEST(FuzzCorpus, ImageHeader) {
  replay("image_header", fuzz::image_header_input,
         {"png_30000_square", "png_bad_crc", "png_bit_depth_3", "jpeg_no_sof", "empty"});
}

}  // namespace
}  // namespace rgbdt::core
