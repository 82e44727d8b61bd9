// Every app on broken, unusual and hostile input (issue "Never silently wrong").
//
// Each case copies a pristine simulated session, breaks one thing in it, runs the app as a
// user would and checks the contract every app keeps on bad input:
//   - it ends by itself (no signal, no hang) with an exit code 1..127,
//   - its message names the file at fault,
//   - it leaves no output that looks complete: no extrinsics YAML, and no summary.json or
//     report.md unless it says FAIL,
//   - it stays within a memory cap (RLIMIT_AS; not under AddressSanitizer, which reserves
//     terabytes of address space for its shadow memory).
// Valid but unusual sessions (thermal only, no cameras) must instead succeed.
//
// The pristine sessions come from the fixture test robustness_sessions (rgbdt_sim), run once
// before these tests by ctest.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"

namespace fs = std::filesystem;

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kUnderAsan = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kUnderAsan = true;
#else
constexpr bool kUnderAsan = false;
#endif
#else
constexpr bool kUnderAsan = false;
#endif

// The apps load PCL, VTK, MRPT and OpenCV: about 1 GB of address space before any work.
// 3 GB leaves room for real work on the small sessions and stops a runaway allocation of a
// crafted header long before the machine notices.
constexpr rlim_t kAddressSpaceCap = 3ull << 30;
constexpr int kTimeoutS = 180;

struct RunResult {
  bool exited = false;
  int exit_code = -1;
  int signal = 0;
  bool timed_out = false;
  long peak_rss_mb = 0;  // the app's maximum resident set size
  std::string output;    // stdout and stderr
  std::string command;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_bytes(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << p;
}

// Runs <bin>/<app> args... under the memory cap and a wall-clock limit. A file size cap
// (RLIMIT_FSIZE, with SIGXFSZ ignored) makes every write past it fail with EFBIG, as on a
// full disk.
RunResult run_app(const std::string& app, const std::vector<std::string>& args, const fs::path& log,
                  rlim_t file_size_cap = RLIM_INFINITY) {
  RunResult r;
  const std::string program = rgbdt::test::built_program(app);
  r.command = program;
  for (const auto& a : args) r.command += " " + a;
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (!kUnderAsan) {
      const rlimit cap{kAddressSpaceCap, kAddressSpaceCap};
      ::setrlimit(RLIMIT_AS, &cap);
    }
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    if (file_size_cap != RLIM_INFINITY) {
      // The cap holds for the log too: callers keep it above what the app prints.
      ::signal(SIGXFSZ, SIG_IGN);
      const rlimit fsize{file_size_cap, file_size_cap};
      ::setrlimit(RLIMIT_FSIZE, &fsize);
    }
    std::vector<std::string> all = {program};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(program.c_str(), argv.data());
    ::_exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kTimeoutS);
  int status = 0;
  rusage usage{};
  while (true) {
    const pid_t done = ::wait4(pid, &status, WNOHANG, &usage);
    if (done == pid) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::wait4(pid, &status, 0, &usage);
      r.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  r.peak_rss_mb = usage.ru_maxrss / 1024;
  if (WIFEXITED(status)) {
    r.exited = true;
    r.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
  }
  r.output = slurp(log);
  return r;
}

fs::path pristine(const std::string& which) {
  const fs::path p = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "robustness_sessions" / which;
  if (!fs::exists(p / "session.yaml")) {
    ADD_FAILURE() << "missing " << p << ": run the fixture test robustness_sessions first";
  }
  return p;
}

// A fresh copy of a pristine session for one case.
fs::path copy_session(const std::string& which, const std::string& name) {
  const fs::path dst = rgbdt::test::temp_path(name);
  fs::create_directories(dst.parent_path());
  fs::copy(pristine(which), dst, fs::copy_options::recursive);
  return dst;
}

void replace_in_file(const fs::path& p, const std::string& from, const std::string& to) {
  std::string text = slurp(p);
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << "'" << from << "' not in " << p;
  text.replace(at, from.size(), to);
  write_bytes(p, text);
}

void replace_regex_in_file(const fs::path& p, const std::string& pattern, const std::string& to) {
  const std::string text = slurp(p);
  const std::string changed =
      std::regex_replace(text, std::regex(pattern), to, std::regex_constants::format_first_only);
  ASSERT_NE(changed, text) << "/" << pattern << "/ not in " << p;
  write_bytes(p, changed);
}

// The outputs that tell a user (or a script) a run finished.
std::vector<fs::path> complete_looking_outputs(const fs::path& out) {
  std::vector<fs::path> found;
  if (!fs::exists(out)) return found;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    // A report that says the run failed is a result too, and an honest one.
    if ((name == "summary.json" || name == "report.md") &&
        slurp(e.path()).find("FAIL") == std::string::npos) {
      found.push_back(e.path());
    }
    if (name.rfind("extrinsics_", 0) == 0 && name.find(".rejected.") == std::string::npos &&
        e.path().extension() == ".yaml") {
      found.push_back(e.path());
    }
  }
  return found;
}

// The contract on bad input.
void expect_clean_failure(const RunResult& r, const std::string& names, const fs::path& out) {
  SCOPED_TRACE(r.command);
  EXPECT_FALSE(r.timed_out) << "ran past " << kTimeoutS << " s\n" << r.output;
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.output;
  ASSERT_TRUE(r.exited);
  EXPECT_GE(r.exit_code, 1) << r.output;
  EXPECT_LE(r.exit_code, 127) << r.output;
  EXPECT_NE(r.output.find(names), std::string::npos)
      << "the message does not name '" << names << "':\n"
      << r.output;
  for (const auto& p : complete_looking_outputs(out)) {
    ADD_FAILURE() << "a failed run left " << p << ", which looks like a finished result";
  }
}

// The contract on valid but unusual input.
void expect_success(const RunResult& r, const fs::path& out) {
  SCOPED_TRACE(r.command);
  EXPECT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.output;
  ASSERT_TRUE(r.exited);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

void expect_valid_summary_json(const fs::path& summary) {
  ASSERT_TRUE(fs::exists(summary)) << summary;
  const std::string text = slurp(summary);
  // JSON has no inf or nan; a writer that prints them writes a file no parser reads.
  EXPECT_EQ(std::regex_search(text, std::regex(R"(:\s*-?(inf|nan)\b)", std::regex::icase)), false)
      << summary << ":\n"
      << text;
}

// ---------------------------------------------------------------- calibration sessions

RunResult calibrate(const fs::path& session, const fs::path& out, const std::string& tag) {
  return run_app("rgbdt_calibrate", {session.string(), "--out", out.string()},
                 rgbdt::test::temp_path(tag + ".log"));
}

class Calibrate : public ::testing::Test {
 protected:
  void SetUp() override {
    session_ = copy_session("cal", "session");
    out_ = rgbdt::test::temp_path("out");
  }
  RunResult run() { return calibrate(session_, out_, "calibrate"); }
  fs::path session_, out_;
};

// A full disk: every output larger than 8 kB fails to be written (the extrinsics YAML,
// 1.5 kB, and report.md, 4 kB, fit; the overlay JPEGs, 20 kB thermal and 70-80 kB RGB, do
// not, so every camera fails). The run must say which file failed and
// leave no report.md or extrinsics YAML that looks like a finished calibration.
TEST_F(Calibrate, FullDiskIsAnErrorNamingTheFile) {
  const RunResult r = run_app("rgbdt_calibrate", {session_.string(), "--out", out_.string()},
                              rgbdt::test::temp_path("calibrate.log"), 8 * 1024);
  expect_clean_failure(r, out_.string(), out_);
}

TEST_F(Calibrate, ZeroBytePcdIsAnErrorNamingIt) {
  write_bytes(session_ / "clouds/000.pcd", "");
  expect_clean_failure(run(), "000.pcd", out_);
}

TEST_F(Calibrate, RandomBytesPcdIsAnErrorNamingIt) {
  std::mt19937 rng(7);
  std::string bytes(4096, '\0');
  for (auto& c : bytes) c = static_cast<char>(rng());
  write_bytes(session_ / "clouds/001.pcd", bytes);
  expect_clean_failure(run(), "001.pcd", out_);
}

std::string pcd_header(const std::string& data_kind, int points) {
  std::ostringstream h;
  h << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
       "TYPE F F F\nCOUNT 1 1 1\nWIDTH "
    << points << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << points << "\nDATA " << data_kind
    << "\n";
  return h.str();
}

std::string u32(std::uint32_t v) {
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((v >> (8 * i)) & 0xff);
  return s;
}

// Overwrites `bytes` at `offset` within point `index` of a DATA binary PCD written by rgbdt_sim
// (fields x y z intensity ring t: 22 bytes a point, ring at byte 16, t at byte 18).
void patch_binary_point(const fs::path& pcd, std::size_t index, std::size_t offset,
                        const std::string& bytes) {
  std::string text = slurp(pcd);
  ASSERT_NE(text.find("FIELDS x y z intensity ring t\nSIZE 4 4 4 4 2 4\n"), std::string::npos)
      << pcd;
  const std::string data_line = "DATA binary\n";
  const auto at = text.find(data_line);
  ASSERT_NE(at, std::string::npos) << pcd;
  const std::size_t byte = at + data_line.size() + 22 * index + offset;
  ASSERT_LE(byte + bytes.size(), text.size()) << pcd;
  text.replace(byte, bytes.size(), bytes);
  write_bytes(pcd, text);
}

std::string f32(float v) {
  std::string s(4, '\0');
  std::memcpy(s.data(), &v, 4);
  return s;
}

// Compressed size 0 with the uncompressed size of 1000 points, and with 0 (PCL's reader
// segfaults on the second).
TEST_F(Calibrate, CompressedPcdOfCompressedSizeZeroIsAnError) {
  for (const std::uint32_t uncompressed : {12000u, 0u}) {
    SCOPED_TRACE("uncompressed size " + std::to_string(uncompressed));
    write_bytes(session_ / "clouds/000.pcd", pcd_header("binary_compressed", 1000) + u32(0) +
                                                 u32(uncompressed) + std::string(64, '\0'));
    expect_clean_failure(run(), "000.pcd", out_);
  }
}

TEST_F(Calibrate, CompressedPcdClaimingAHugeSizeIsRefusedBeforeAllocating) {
  // 600 kB of data that claims to decompress to ~4 GB.
  std::mt19937 rng(3);
  std::string data(600000, '\0');
  for (auto& c : data) c = static_cast<char>(rng());
  write_bytes(session_ / "clouds/000.pcd",
              pcd_header("binary_compressed", 357913941) + u32(600000) + u32(0xFFFFFFF0u) + data);
  expect_clean_failure(run(), "000.pcd", out_);
}

TEST_F(Calibrate, CompressedPcdWithInflatedPointCountIsAnError) {
  // A whole binary_compressed cloud whose WIDTH and POINTS claim 4x the points it holds:
  // PCL only warns; the scrambled points must not reach the detector.
  const auto loaded = rgbdt::cloud::load_pcd((session_ / "clouds/000.pcd").string());
  const fs::path p = session_ / "clouds/000.pcd";
  rgbdt::cloud::save_pcd(p.string(), *loaded.cloud, rgbdt::cloud::PcdFormat::kBinaryCompressed);
  const std::string n = std::to_string(loaded.cloud->size());
  const std::string n4 = std::to_string(4 * loaded.cloud->size());
  replace_in_file(p, "WIDTH " + n + "\n", "WIDTH " + n4 + "\n");
  replace_in_file(p, "POINTS " + n + "\n", "POINTS " + n4 + "\n");
  expect_clean_failure(run(), "000.pcd", out_);
}

// A binary PCD whose header claims far more points than the file holds: an error naming the
// file, not std::bad_alloc from a reserve of the claimed size.
TEST_F(Calibrate, PcdHeaderClaimingMorePointsThanTheFileHoldsNamesTheFile) {
  write_bytes(session_ / "clouds/001.pcd",
              pcd_header("binary", 2000000000) + std::string(1200, '\0'));
  const auto r = run();
  expect_clean_failure(r, "001.pcd", out_);
  EXPECT_EQ(r.output.find("bad_alloc"), std::string::npos) << r.output;
}

TEST_F(Calibrate, RingOutOfRangeIsAnError) {
  patch_binary_point(session_ / "clouds/000.pcd", 100, 16, std::string("\xff\xff", 2));
  expect_clean_failure(run(), "000.pcd", out_);
}

// A YAML value of the wrong type: the message names the file and the key, not yaml-cpp's
// "invalid node; this may result from using a map iterator...".
TEST_F(Calibrate, YamlTypeErrorNamesTheFileAndTheKey) {
  replace_regex_in_file(session_ / "rgb.yaml", R"(image_width: [0-9]+)", "image_width: {a: 1}");
  const auto r = run();
  expect_clean_failure(r, "rgb.yaml", out_);
  EXPECT_NE(r.output.find("image_width"), std::string::npos) << r.output;
}

TEST_F(Calibrate, PrincipalPointOutsideTheImageIsAnError) {
  replace_regex_in_file(session_ / "rgb.yaml", R"(data: \[1335\.2, 0, [0-9.]+,)",
                        "data: [1335.2, 0, 99999,");
  expect_clean_failure(run(), "rgb.yaml", out_);
}

TEST_F(Calibrate, NegativeDistortionRowsIsAnError) {
  replace_in_file(session_ / "rgb.yaml", "  rows: 1\n  cols: 5", "  rows: -1\n  cols: 5");
  expect_clean_failure(run(), "rgb.yaml", out_);
}

TEST_F(Calibrate, InfiniteRadiusIsAnError) {
  replace_in_file(session_ / "session.yaml", "radius: 0.3", "radius: .inf");
  expect_clean_failure(run(), "session.yaml", out_);
}

TEST_F(Calibrate, NegativeBoardSizeIsAnError) {
  replace_in_file(session_ / "session.yaml", "board_size: [1.2, 1.2]", "board_size: [-1.2, 0]");
  expect_clean_failure(run(), "session.yaml", out_);
}

TEST_F(Calibrate, DuplicateKeyIsAnError) {
  replace_in_file(session_ / "session.yaml", "target: {type: circle_hole, radius: 0.3,",
                  "target: {type: circle_hole, radius: 0.5, radius: 0.3,");
  expect_clean_failure(run(), "radius", out_);
}

TEST_F(Calibrate, MissingImageIsFoundBeforeTheWork) {
  fs::remove(session_ / "rgb/001.png");
  const auto r = run();
  expect_clean_failure(r, "001.png", out_);
  // Preflight: nothing of the long work has started, so nothing at all is written.
  EXPECT_FALSE(fs::exists(out_) && !fs::is_empty(out_)) << r.output;
}

TEST_F(Calibrate, ImageOfAnotherSizeThanItsCameraInfoIsAnError) {
  const cv::Mat small(482, 644, CV_8UC1, cv::Scalar(128));
  ASSERT_TRUE(cv::imwrite((session_ / "rgb/000.png").string(), small));
  expect_clean_failure(run(), "000.png", out_);
}

// A PNG chunk: length, type, data, CRC.
std::string png_chunk(const std::string& type, const std::string& data) {
  auto be32 = [](std::uint32_t v) {
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i) s[i] = static_cast<char>((v >> (24 - 8 * i)) & 0xff);
    return s;
  };
  const std::string body = type + data;
  const auto crc =
      ::crc32(0, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()));
  return be32(static_cast<std::uint32_t>(data.size())) + body +
         be32(static_cast<std::uint32_t>(crc));
}

// A valid PNG of 30000 x 30000 RGB pixels, all black: 2.7 GB decoded from 2.6 MB of file.
std::string decompression_bomb_png() {
  constexpr std::uint32_t kSide = 30000;
  std::string ihdr;
  for (const std::uint32_t v : {kSide, kSide}) {
    for (int i = 0; i < 4; ++i) ihdr += static_cast<char>((v >> (24 - 8 * i)) & 0xff);
  }
  ihdr += std::string("\x08\x02\x00\x00\x00", 5);  // 8-bit RGB
  z_stream z{};
  EXPECT_EQ(::deflateInit(&z, 1), Z_OK);
  const std::string row(1 + 3 * kSide, '\0');  // filter byte + pixels
  std::string idat;
  std::string buffer(1 << 16, '\0');
  for (std::uint32_t y = 0; y <= kSide; ++y) {
    const bool last = y == kSide;
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(row.data()));
    z.avail_in = last ? 0 : static_cast<uInt>(row.size());
    do {
      z.next_out = reinterpret_cast<Bytef*>(buffer.data());
      z.avail_out = static_cast<uInt>(buffer.size());
      ::deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
      idat.append(buffer.data(), buffer.size() - z.avail_out);
    } while (z.avail_out == 0);
  }
  ::deflateEnd(&z);
  return std::string("\x89PNG\r\n\x1a\n", 8) + png_chunk("IHDR", ihdr) + png_chunk("IDAT", idat) +
         png_chunk("IEND", "");
}

// The header is read first: the image is refused for its size before a decoder allocates
// 2.7 GB for it.
TEST_F(Calibrate, HugePngHeaderIsRefusedBeforeDecoding) {
  write_bytes(session_ / "rgb/000.png", decompression_bomb_png());
  const auto r = run();
  expect_clean_failure(r, "000.png", out_);
  // The apps peak at 100-300 MB on these sessions (under AddressSanitizer too).
  EXPECT_LT(r.peak_rss_mb, 1024) << r.output;
}

TEST_F(Calibrate, IntrinsicsNamingANonYamlFileNamesThePathNotItsContents) {
  replace_in_file(session_ / "session.yaml", "rgb: {intrinsics: rgb.yaml}",
                  "rgb: {intrinsics: clouds/000.pcd}");
  const auto r = run();
  expect_clean_failure(r, "000.pcd", out_);
  EXPECT_EQ(r.output.find("Point Cloud Data"), std::string::npos)
      << "the message quotes the file's contents:\n"
      << r.output;
}

TEST_F(Calibrate, LongCameraNameDoesNotCrash) {
  const std::string name(100, 'c');
  replace_in_file(session_ / "session.yaml", "  rgb: {intrinsics: rgb.yaml}",
                  "  " + name + ": {intrinsics: rgb.yaml}");
  replace_in_file(session_ / "session.yaml", "images: {rgb: rgb/000.png",
                  "images: {" + name + ": rgb/000.png");
  replace_in_file(session_ / "session.yaml", "images: {rgb: rgb/001.png",
                  "images: {" + name + ": rgb/001.png");
  const auto r = run();
  EXPECT_EQ(r.signal, 0) << r.output;
  EXPECT_FALSE(r.timed_out);
  ASSERT_TRUE(r.exited);
  if (r.exit_code != 0) {
    EXPECT_NE(r.output.find(name.substr(0, 20)), std::string::npos) << r.output;
  }
}

// ---------------------------------------------------------------- mapping sessions

class Mapper : public ::testing::Test {
 protected:
  void SetUp() override {
    session_ = copy_session("map", "session");
    out_ = rgbdt::test::temp_path("out");
  }
  RunResult run() {
    return run_app("rgbdt_mapper",
                   {session_.string(), "--calib", (session_ / "true_calib").string(), "--out",
                    out_.string(), "--lidar", "clouds"},
                   rgbdt::test::temp_path("mapper.log"));
  }
  fs::path yaml() const { return session_ / "session.yaml"; }
  fs::path session_, out_;
};

TEST_F(Mapper, ThermalOnlyRigMaps) {
  replace_regex_in_file(yaml(), R"(\n  rgb: \{[^\n]*\})", "");
  const auto r = run();
  expect_success(r, out_);
  expect_valid_summary_json(out_ / "summary.json");
}

TEST_F(Mapper, NoCamerasMakesALidarOnlyMap) {
  replace_regex_in_file(yaml(), R"(cameras:\n(  [^\n]*\n)+)", "cameras: {}\n");
  const auto r = run();
  expect_success(r, out_);
  expect_valid_summary_json(out_ / "summary.json");
}

TEST_F(Mapper, RgbIndexWithOnlyItsHeaderMapsWithoutRgb) {
  write_bytes(session_ / "rgb/index.csv", "time_s,file\n");
  const auto r = run();
  expect_success(r, out_);
  expect_valid_summary_json(out_ / "summary.json");
}

TEST_F(Mapper, RgbFramesOutsideTheLidarSpanMapWithoutRgb) {
  write_bytes(session_ / "rgb/index.csv", "time_s,file\n5000.0,00000.png\n5000.5,00001.png\n");
  const auto r = run();
  expect_success(r, out_);
  expect_valid_summary_json(out_ / "summary.json");
}

TEST_F(Mapper, FramesNamingAFolderIsAnError) {
  replace_in_file(yaml(), "frames: rgb/index.csv", "frames: rgb");
  expect_clean_failure(run(), "rgb", out_);
}

// The message names the file and what was expected of it, not the file's first line.
TEST_F(Mapper, FramesNamingAnotherKindOfFileNamesThePathNotItsContents) {
  replace_in_file(yaml(), "frames: rgb/index.csv", "frames: rgb.yaml");
  const auto r = run();
  expect_clean_failure(r, "rgb.yaml", out_);
  EXPECT_EQ(r.output.find("image_width"), std::string::npos)
      << "the message quotes the file's contents:\n"
      << r.output;
}

// A YAML syntax error is reported with the file it is in, not as yaml-cpp's bare "error at
// line 3, column 6".
TEST_F(Mapper, YamlSyntaxErrorNamesTheFile) {
  write_bytes(session_ / "ground_truth.yaml", "x: [\n" + slurp(session_ / "ground_truth.yaml"));
  expect_clean_failure(run(), "ground_truth.yaml", out_);
}

TEST_F(Mapper, NanInExtrinsicsIsAnError) {
  replace_regex_in_file(session_ / "true_calib/extrinsics_rgb.yaml", R"(translation: \[[-0-9.e]+,)",
                        "translation: [.nan,");
  expect_clean_failure(run(), "extrinsics_rgb.yaml", out_);
}

// A correct T_lidar_thermal (parent_frame: lidar) is the same calibration as the session's
// T_thermal_lidar: the map's thermal error against the simulated truth stays what it is with
// the original file (0.09 K mean). Used the wrong way round, the points sample the image a
// quarter of a metre off and the mean error is kelvins.
TEST_F(Mapper, ExtrinsicsWithTheLidarAsParentAreInverted) {
  const fs::path file = session_ / "true_calib/extrinsics_thermal.yaml";
  const rgbdt::core::Extrinsics thermal_lidar = rgbdt::core::read_extrinsics(file.string());
  ASSERT_EQ(thermal_lidar.parent_frame, "thermal");
  rgbdt::core::Extrinsics lidar_thermal = rgbdt::core::inverted(thermal_lidar);
  ASSERT_EQ(lidar_thermal.parent_frame, "lidar");
  write_bytes(file, rgbdt::core::format_extrinsics(lidar_thermal));
  const auto r = run();
  expect_success(r, out_);
  const std::string summary = slurp(out_ / "summary.json");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(summary, m,
                                std::regex(R"("thermal_error_k":\s*\{\s*"mean":\s*([-0-9.eE+]+))")))
      << summary;
  EXPECT_LT(std::stod(m[1].str()), 0.5) << "mean thermal error [K] with T_lidar_thermal";
}

TEST_F(Mapper, PointTimeThatIsNotFiniteIsAnError) {
  patch_binary_point(session_ / "clouds/00002.pcd", 100, 18,
                     f32(std::numeric_limits<float>::quiet_NaN()));
  expect_clean_failure(run(), "00002.pcd", out_);
}

TEST_F(Mapper, PointTimeFarOutsideItsCloudIsAnError) {
  patch_binary_point(session_ / "clouds/00002.pcd", 100, 18, f32(1e30f));
  expect_clean_failure(run(), "00002.pcd", out_);
}

TEST_F(Mapper, HalfSizeThermalFramesAreAnError) {
  for (const auto& e : fs::directory_iterator(session_ / "thermal")) {
    if (e.path().extension() != ".png") continue;
    cv::Mat img = cv::imread(e.path().string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << e.path();
    cv::Mat half;
    cv::resize(img, half, cv::Size(img.cols / 2, img.rows / 2), 0, 0, cv::INTER_NEAREST);
    ASSERT_TRUE(cv::imwrite(e.path().string(), half));
  }
  expect_clean_failure(run(), ".png", out_);
}

TEST_F(Mapper, EightBitThermalFramesAreAnError) {
  for (const auto& e : fs::directory_iterator(session_ / "thermal")) {
    if (e.path().extension() != ".png") continue;
    cv::Mat img = cv::imread(e.path().string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << e.path();
    cv::Mat eight;
    img.convertTo(eight, CV_8U, 1.0 / 256.0);
    ASSERT_TRUE(cv::imwrite(e.path().string(), eight));
  }
  expect_clean_failure(run(), ".png", out_);
}

TEST_F(Mapper, AbsurdKelvinPerCountIsAnError) {
  replace_in_file(yaml(), "kelvin_per_count: 0.04", "kelvin_per_count: 1e300");
  expect_clean_failure(run(), "kelvin_per_count", out_);
}

TEST_F(Mapper, NegativeKelvinIsAnError) {
  replace_in_file(yaml(), "offset_k: 0", "offset_k: -5000");
  expect_clean_failure(run(), "offset_k", out_);
}

TEST_F(Mapper, TimeWithTrailingGarbageIsAnError) {
  replace_in_file(session_ / "rgb/index.csv", "100.002,", "100.002xyz,");
  expect_clean_failure(run(), "index.csv", out_);
}

TEST_F(Mapper, HexTimeIsAnError) {
  replace_in_file(session_ / "rgb/index.csv", "100.002,", "0x64,");
  expect_clean_failure(run(), "index.csv", out_);
}

TEST_F(Mapper, MissingFrameIsFoundBeforeTheWork) {
  fs::remove(session_ / "thermal/00003.png");
  const auto r = run();
  expect_clean_failure(r, "00003.png", out_);
  EXPECT_FALSE(fs::exists(out_ / "map.ply")) << r.output;
  EXPECT_FALSE(fs::exists(out_ / "trajectory.csv")) << r.output;
}

// ---------------------------------------------------------------- raw recordings

class TiltLidar : public ::testing::Test {
 protected:
  RunResult info(const fs::path& rawlog) {
    return run_app("rgbdt_tilt_lidar", {"info", rawlog.string()},
                   rgbdt::test::temp_path("info.log"));
  }
};

// The session's rawlog is gzip-compressed; the lengths and counts are in the serialised
// records, so the forged words go into the uncompressed stream (a plain rawlog MRPT reads too).
TEST_F(TiltLidar, RecordClaimingFourGigabytesIsRefused) {
  const fs::path dir = rgbdt::test::temp_dir("rawlog");
  ASSERT_EQ(std::system(("gzip -dc " + (pristine("map") / "lidar.rawlog").string() + " > " +
                         (dir / "plain.rawlog").string())
                            .c_str()),
            0);
  const std::string real = slurp(dir / "plain.rawlog");
  ASSERT_GT(real.size(), 4096u);
  // The first record is a CObservation2DRangeScan of the simulated UTM-30LX: its count of
  // 1081 ranges is the length MRPT's resizeScan allocates from (a segfault under a memory
  // cap, 23 GB without one, before the rawlog reader bounded it).
  const std::size_t count_at = real.find(u32(1081));
  ASSERT_LT(count_at, 512u) << "no range count of 1081 in the first record";
  std::vector<std::size_t> offsets = {count_at};
  // And every aligned word of the first bytes, whichever field the reader trusts.
  for (std::size_t at = 0; at + 4 <= 48; at += 4) offsets.push_back(at);
  for (const std::size_t at : offsets) {
    std::string bytes = real;
    bytes.replace(at, 4, u32(0xFFFFFFF0u));
    const std::string name = "claim_" + std::to_string(at) + ".rawlog";
    write_bytes(dir / name, bytes);
    const auto r = info(dir / name);
    SCOPED_TRACE("word at byte " + std::to_string(at));
    EXPECT_FALSE(r.timed_out) << r.output;
    EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.output;
    EXPECT_LT(r.peak_rss_mb, 1024) << r.output;
    if (at == count_at) expect_clean_failure(r, name, dir / "none");
  }
}

// Three kinds of gzip file that hold no rawlog: a valid gzip stream of random bytes, a gzip
// header followed by random bytes (a damaged stream), and a gzip stream of nothing.
TEST_F(TiltLidar, GzipOfGarbageIsNotARawlog) {
  const fs::path dir = rgbdt::test::temp_dir("gz");
  std::mt19937 rng(11);
  std::string bytes(20000, '\0');
  for (auto& c : bytes) c = static_cast<char>(rng());
  write_bytes(dir / "garbage.bin", bytes);
  write_bytes(dir / "empty.bin", "");
  for (const char* name : {"garbage", "empty"}) {
    const std::string in = (dir / (std::string(name) + ".bin")).string();
    const std::string out = (dir / (std::string(name) + ".rawlog")).string();
    ASSERT_EQ(std::system(("gzip -c " + in + " > " + out).c_str()), 0);
  }
  write_bytes(dir / "damaged.rawlog",
              std::string("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03", 10) + bytes);
  for (const char* name : {"garbage.rawlog", "damaged.rawlog", "empty.rawlog"}) {
    SCOPED_TRACE(name);
    expect_clean_failure(info(dir / name), name, dir / "none");
  }
}

// rgbdt_import on bags that are not bags, or whose records lie about their lengths: exit 1
// naming the file, nothing left in --out, memory bounded by the cap. The real bags are
// rosbag2's own test recordings (../shared/data/rosbag2), cut or with a length word rewritten.
class Import : public ::testing::Test {
 protected:
  RunResult import(const fs::path& bag, const fs::path& out) {
    return run_app("rgbdt_import",
                   {bag.string(), "--out", out.string(), "--kind", "mapping", "--lidar", "/points"},
                   rgbdt::test::temp_path("import.log"));
  }
  static fs::path rosbag2(const std::string& relative) {
    const fs::path p = fs::path(RGBDT_SHARED_DATA_DIR) / "rosbag2" / relative;
    if (!fs::exists(p)) ADD_FAILURE() << "missing real-data file " << p;
    return p;
  }
};

TEST_F(Import, FilesThatAreNoBagAreErrorsNamingThem) {
  const fs::path dir = rgbdt::test::temp_dir("bags");
  std::mt19937 rng(5);
  std::string noise(100000, '\0');
  for (auto& c : noise) c = static_cast<char>(rng());
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"empty.mcap", ""},
      {"noise.mcap", noise},
      {"noise.bag", noise},
      {"mcap_magic.mcap", std::string("\x89MCAP0\r\n", 8) + noise.substr(0, 5000)},
      {"ros1_magic.bag", "#ROSBAG V2.0\n" + noise.substr(0, 5000)},
      {"sqlite_magic.db3", std::string("SQLite format 3\0", 16) + noise.substr(0, 5000)},
  };
  for (const auto& [name, bytes] : cases) {
    write_bytes(dir / name, bytes);
    const fs::path out = dir / ("out_" + name);
    expect_clean_failure(import(dir / name, out), name, out);
    EXPECT_FALSE(fs::exists(out)) << name << ": a failed import left " << out;
  }
}

TEST_F(Import, RealMcapCutOrLyingAboutALengthIsRefused) {
  const fs::path dir = rgbdt::test::temp_dir("mcap");
  const std::string real = slurp(rosbag2("rosbag2_py/test/resources/mcap/talker/talker.mcap"));
  ASSERT_GT(real.size(), 200u);
  // Every 64-bit length word of the first records claims ~2^62 bytes, one file each; and
  // the file cut at a few places (a cut recording without a summary reads to its last whole
  // record and is not an error; the topic asked for is not in it either way).
  int n = 0;
  for (std::size_t at = 8; at + 8 <= std::min<std::size_t>(real.size(), 72); at += 1) {
    std::string bytes = real;
    bytes.replace(at, 8, std::string("\x00\x00\x00\x00\x00\x00\x00\x40", 8));
    const std::string name = "claim_" + std::to_string(at) + ".mcap";
    write_bytes(dir / name, bytes);
    const auto r = import(dir / name, dir / ("out_" + name));
    SCOPED_TRACE(name);
    EXPECT_FALSE(r.timed_out) << r.output;
    EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.output;
    EXPECT_NE(r.exit_code, 0) << r.output;
    ++n;
  }
  for (const std::size_t keep :
       {std::size_t{9}, std::size_t{40}, real.size() / 2, real.size() - 3}) {
    const std::string name = "cut_" + std::to_string(keep) + ".mcap";
    write_bytes(dir / name, real.substr(0, keep));
    expect_clean_failure(import(dir / name, dir / ("out_" + name)), name, dir / ("out_" + name));
  }
  EXPECT_GT(n, 50);
}

TEST_F(Import, ConfigFileWithAnUnknownKeyNamesTheFileAndTheKey) {
  const fs::path dir = rgbdt::test::temp_dir("config");
  write_bytes(dir / "import.yaml", "kind: mapping\nlidr: /points\n");
  const auto r = run_app(
      "rgbdt_import",
      {"--config", (dir / "import.yaml").string(), "x.mcap", "--out", (dir / "out").string()},
      rgbdt::test::temp_path("import.log"));
  expect_clean_failure(r, "import.yaml", dir / "out");
  EXPECT_NE(r.output.find("lidr"), std::string::npos) << r.output;
}

}  // namespace
