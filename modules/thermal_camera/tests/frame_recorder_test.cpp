#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/thermal_camera/frame_recorder.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::thermal_camera;
namespace fs = std::filesystem;

namespace {


Frame make_frame(int type, const std::string& format, int seed) {
  Frame f;
  f.image.create(48, 64, type);
  cv::randu(f.image, cv::Scalar::all(0), cv::Scalar::all(type == CV_16UC1 ? 16384 : 256));
  f.image.at<uchar>(0, 0) = static_cast<uchar>(seed);  // frames differ
  f.pixel_format = format;
  return f;
}

size_t count_files(const fs::path& dir, const std::string& ext) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ext ? 1 : 0;
  return n;
}

}  // namespace

TEST(FrameRecorder, SixteenBitFramesRoundTripExactlyWithTheirTimes) {
  const fs::path dir = rgbdt::test::temp_path("rec");
  std::vector<Frame> frames;
  {
    FrameRecorderOptions o;
    o.out_dir = dir.string();
    FrameRecorder recorder(o);
    for (int i = 0; i < 5; ++i) {
      frames.push_back(make_frame(CV_16UC1, "Mono16", i));
      recorder.write(frames.back(), 100.0 + 0.04 * i);
    }
  }
  const auto index = rgbdt::core::read_time_index((dir / "index.csv").string());
  ASSERT_EQ(index.size(), 5u);
  for (size_t i = 0; i < index.size(); ++i) {
    EXPECT_NEAR(index[i].time_s, 100.0 + 0.04 * i, 1e-6);  // CSV keeps microseconds or better
    const cv::Mat back = cv::imread(index[i].file, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(back.type(), CV_16UC1) << index[i].file;
    EXPECT_EQ(cv::norm(back, frames[i].image, cv::NORM_INF), 0.0) << "PNG is lossless";
  }
  EXPECT_EQ(count_files(dir, ".tmp"), 0u);
  EXPECT_EQ(count_files(dir, ".png"), 5u);
}

TEST(FrameRecorder, WritesMono8AsGreyAndBayerAsColour) {
  const fs::path dir = rgbdt::test::temp_path("rec");
  FrameRecorderOptions o;
  o.out_dir = dir.string();
  FrameRecorder recorder(o);
  const std::string grey = recorder.write(make_frame(CV_8UC1, "Mono8", 1), 1.0);
  const std::string colour = recorder.write(make_frame(CV_8UC1, "BayerRG8", 2), 2.0);
  EXPECT_EQ(cv::imread(grey, cv::IMREAD_UNCHANGED).type(), CV_8UC1);
  EXPECT_EQ(cv::imread(colour, cv::IMREAD_UNCHANGED).type(), CV_8UC3);
}

TEST(FrameRecorder, IndexListsFramesBeforeTheRecorderCloses) {
  const fs::path dir = rgbdt::test::temp_path("rec");
  FrameRecorderOptions o;
  o.out_dir = dir.string();
  o.index_flush_interval_s = 0.0;  // every frame
  FrameRecorder recorder(o);
  recorder.write(make_frame(CV_16UC1, "Mono16", 1), 1.0);
  recorder.write(make_frame(CV_16UC1, "Mono16", 2), 2.0);
  // As a crash right now would leave it:
  EXPECT_EQ(rgbdt::core::read_time_index((dir / "index.csv").string()).size(), 2u);
}

TEST(FrameRecorder, RefusesToOverwriteARecording) {
  const fs::path dir = rgbdt::test::temp_path("rec");
  FrameRecorderOptions o;
  o.out_dir = dir.string();
  { FrameRecorder first(o); }
  try {
    FrameRecorder second(o);
    ADD_FAILURE() << "overwrote " << dir;
  } catch (const rgbdt::core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("index.csv"), std::string::npos) << e.what();
  }
  o.png_compression = 11;
  EXPECT_THROW(FrameRecorder{o}, std::invalid_argument);
}
