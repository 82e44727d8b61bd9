// Image headers read without decoding: sizes agree with OpenCV's decoder on files it
// writes and on real images; oversized, corrupt and truncated headers are refused naming
// the file; image_mismatch names both files.
#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/image_header.hpp"

namespace fs = std::filesystem;
using namespace rgbdt::core;

namespace {

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "image_header";
  fs::create_directories(dir);
  return dir / name;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// CRC-32 (ISO 3309) by table, as PNG chunks carry it.
std::uint32_t png_crc(const std::string& bytes) {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t n = 0; n < 256; ++n) {
    std::uint32_t c = n;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
    table[n] = c;
  }
  std::uint32_t c = 0xffffffffu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xff] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

void put_be32(std::string& s, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) s += static_cast<char>((v >> shift) & 0xff);
}

/// A PNG signature and IHDR chunk (with a correct CRC) and nothing else.
std::string png_header(std::uint32_t width, std::uint32_t height, int depth, int colour,
                       int interlace = 0) {
  std::string chunk = "IHDR";
  put_be32(chunk, width);
  put_be32(chunk, height);
  chunk += static_cast<char>(depth);
  chunk += static_cast<char>(colour);
  chunk += '\0';
  chunk += '\0';
  chunk += static_cast<char>(interlace);
  std::string file = "\x89PNG\r\n\x1a\n";
  put_be32(file, 13);
  file += chunk;
  put_be32(file, png_crc(chunk));
  return file;
}

template <typename Fn>
std::string error_of(Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

void expect_refused(const fs::path& path, const std::string& part) {
  const std::string what = error_of([&] { read_image_header(path.string()); });
  EXPECT_NE(what.find(path.string()), std::string::npos) << what;
  EXPECT_NE(what.find(part), std::string::npos) << "'" << what << "' lacks '" << part << "'";
}

}  // namespace

TEST(ImageHeader, AgreesWithOpenCvOnEveryKindItWrites) {
  struct Kind {
    const char* name;
    int type;
    int bit_depth;
    int channels;
  };
  for (const Kind& k : {Kind{"grey8.png", CV_8UC1, 8, 1}, Kind{"grey16.png", CV_16UC1, 16, 1},
                        Kind{"bgr8.png", CV_8UC3, 8, 3}, Kind{"bgr16.png", CV_16UC3, 16, 3},
                        Kind{"bgra8.png", CV_8UC4, 8, 4}, Kind{"grey8.jpg", CV_8UC1, 8, 1},
                        Kind{"bgr8.jpg", CV_8UC3, 8, 3}}) {
    const auto path = temp_file(k.name);
    cv::Mat image(37, 53, k.type, cv::Scalar::all(100));
    ASSERT_TRUE(cv::imwrite(path.string(), image)) << k.name;
    const ImageHeader h = read_image_header(path.string());
    EXPECT_EQ(h.width, 53) << k.name;
    EXPECT_EQ(h.height, 37) << k.name;
    EXPECT_EQ(h.bit_depth, k.bit_depth) << k.name;
    EXPECT_EQ(h.channels, k.channels) << k.name;
    EXPECT_EQ(h.format, fs::path(k.name).extension() == ".png" ? "png" : "jpeg") << k.name;
  }
}

TEST(ImageHeader, RealThermalPngAndRoadJpegHaveTheirKnownSizes) {
  const fs::path data(RGBDT_SHARED_DATA_DIR);
  const fs::path png = data / "discocal/sample_imgs/tir12/circle_8bit_000.png";
  const fs::path jpg =
      data / "pjlab-sensorscalibration/lidar2camera/auto_calib_v2.0/data/ours/1/calib.jpg";
  for (const auto& p : {png, jpg}) {
    ASSERT_TRUE(fs::exists(p)) << "real data file missing: " << p
                               << " (CI keeps ../shared beside the checkout)";
  }
  const ImageHeader t = read_image_header(png.string());
  EXPECT_EQ(t.width, 640);
  EXPECT_EQ(t.height, 512);
  const cv::Mat decoded = cv::imread(png.string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(t.channels, decoded.channels());
  const ImageHeader r = read_image_header(jpg.string());
  EXPECT_EQ(r.width, 1920);
  EXPECT_EQ(r.height, 1200);
  EXPECT_EQ(r.channels, 3);
}

TEST(ImageHeader, OversizedImagesAreRefusedFromTheHeader) {
  // 30000x30000 RGB: OpenCV allocates 2.7 GB before failing; refused here from 33 bytes.
  const auto huge = temp_file("huge.png");
  write_bytes(huge, png_header(30000, 30000, 8, 2));
  expect_refused(huge, "30000x30000 pixels, expected width and height in 1..20000");
  // The same with a wrong CRC (as a hand-made file has): still refused for its size.
  std::string no_crc = png_header(30000, 30000, 8, 2);
  no_crc.replace(29, 4, std::string(4, '\0'));
  write_bytes(huge, no_crc);
  expect_refused(huge, "30000x30000 pixels");
  // Within the side cap but 20000 x 20000 x 4 channels x 2 bytes = 3.2 GB decoded.
  const auto wide = temp_file("rgba16.png");
  write_bytes(wide, png_header(20000, 20000, 16, 6));
  expect_refused(wide, "3200000000 bytes decoded");
  const auto zero = temp_file("zero.png");
  write_bytes(zero, png_header(0, 10, 8, 0));
  expect_refused(zero, "0x10 pixels");
  // The largest accepted: 20000 x 20000 grey 8-bit (400 MB).
  const auto big = temp_file("big_ok.png");
  write_bytes(big, png_header(20000, 20000, 8, 0));
  EXPECT_EQ(read_image_header(big.string()).width, 20000);
}

TEST(ImageHeader, CorruptAndTruncatedHeadersAreRefused) {
  const auto path = temp_file("broken.img");
  write_bytes(path, "");
  expect_refused(path, "empty");
  write_bytes(path, "GIF89a........................................");
  expect_refused(path, "neither a PNG nor a JPEG");
  write_bytes(path, png_header(640, 512, 16, 0).substr(0, 20));
  expect_refused(path, "ends after 20 bytes");
  std::string bad_crc = png_header(640, 512, 16, 0);
  bad_crc[19] ^= 1;  // width 640 -> 641, CRC unchanged
  write_bytes(path, bad_crc);
  expect_refused(path, "CRC");
  write_bytes(path, png_header(640, 512, 4, 2));
  expect_refused(path, "bit depth 4 is not valid for colour type 2");
  write_bytes(path, png_header(640, 512, 8, 5));
  expect_refused(path, "colour type 5");
  write_bytes(path, png_header(640, 512, 8, 0, 2));
  expect_refused(path, "0/0/2");
  // JPEG: SOI, an APP0 segment whose length runs past the end.
  write_bytes(path, std::string("\xff\xd8\xff\xe0\x40\x00JFIF", 10));
  expect_refused(path, "segment 0xFFE0");
  // JPEG: SOI then start of scan without a SOF.
  write_bytes(path, std::string("\xff\xd8\xff\xda\x00\x02", 6));
  expect_refused(path, "without a SOF");
  // JPEG: SOF with height 0.
  write_bytes(path,
              std::string("\xff\xd8\xff\xc0\x00\x0b\x08\x00\x00\x02\x80\x01\x01\x11\x00", 15));
  expect_refused(path, "640x0 pixels");
  expect_refused(temp_file("missing.png"), "does not exist");
}

TEST(ImageHeader, MismatchWithCameraInfoNamesBothFiles) {
  ImageHeader half{320, 256, 16, 1, "png"};
  const std::string m = image_mismatch(half, 640, 512, "thermal/000.png", "thermal.yaml", 16);
  EXPECT_EQ(
      m,
      "thermal/000.png: image is 320x256, thermal.yaml says 640x512 (image_width x image_height)");
  ImageHeader eight{640, 512, 8, 1, "png"};
  EXPECT_EQ(
      image_mismatch(eight, 640, 512, "thermal/000.png", "thermal.yaml", 16),
      "thermal/000.png: image has 8-bit samples, expected 16-bit for the camera of thermal.yaml");
  ImageHeader ok{640, 512, 16, 1, "png"};
  EXPECT_EQ(image_mismatch(ok, 640, 512, "thermal/000.png", "thermal.yaml", 16), "");
  EXPECT_EQ(image_mismatch(ok, 640, 512, "thermal/000.png", "thermal.yaml"), "");
  ImageHeader one_bit{640, 512, 1, 1, "png"};
  EXPECT_NE(image_mismatch(one_bit, 640, 512, "a.png", "c.yaml").find("expected 8 or 16"),
            std::string::npos);
  const std::string what =
      error_of([&] { check_image_matches(half, 640, 512, "thermal/000.png", "thermal.yaml"); });
  EXPECT_EQ(
      what,
      "thermal/000.png: image is 320x256, thermal.yaml says 640x512 (image_width x image_height)");
  EXPECT_EQ(error_of([&] { check_image_matches(ok, 640, 512, "t.png", "c.yaml", 16); }),
            "(no error)");
}
