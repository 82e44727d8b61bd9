// Runs the rgbdt_camera program: recording from Aravis's in-process fake camera, stopping
// with SIGINT, and the Tau2 subcommand against the pty emulator.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "rgbdt/core/time_index.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"
#include "rgbdt/thermal_camera/tau2.hpp"

extern char** environ;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

std::string program() { return rgbdt::test::built_program("rgbdt_camera"); }

using rgbdt::test::temp_dir;

/// Starts the program with its output in `log`; returns the pid.
pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
  return rgbdt::test::spawn_with_log(program(), args, log);
}

/// Waits for the process at most `limit`; kills it (and fails) if it takes longer.
int wait_exit(pid_t pid, std::chrono::seconds limit) {
  const auto deadline = Clock::now() + limit;
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (Clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      ADD_FAILURE() << "program did not exit within " << limit.count() << " s";
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

int run(const std::vector<std::string>& args, const fs::path& log) {
  return wait_exit(spawn(args, log), std::chrono::seconds(60));
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Every index entry is a whole, readable PNG, and no other PNG or temporary is there.
void expect_consistent_recording(const fs::path& out, int expected_type) {
  const auto index = rgbdt::core::read_time_index((out / "index.csv").string());
  size_t pngs = 0, temporaries = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    // Temporaries are hidden siblings (core::write_file_atomic).
    const bool hidden = e.path().filename().string().front() == '.';
    pngs += !hidden && e.path().extension() == ".png" ? 1 : 0;
    temporaries += hidden ? 1 : 0;
  }
  EXPECT_EQ(temporaries, 0u);
  EXPECT_EQ(pngs, index.size()) << "PNG files not in the index (or listed but missing)";
  for (size_t i = 0; i < index.size(); ++i) {
    const cv::Mat image = cv::imread(index[i].file, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << index[i].file;
    EXPECT_EQ(image.type(), expected_type) << index[i].file;
    if (i > 0) {
      EXPECT_GT(index[i].time_s, index[i - 1].time_s) << i;
    }
  }
}

}  // namespace

TEST(RgbdtCamera, HelpExplainsTheSubcommands) {
  const auto dir = temp_dir("help");
  EXPECT_EQ(run({"--help"}, dir / "log"), 0);
  const std::string text = slurp(dir / "log");
  for (const char* word : {"list", "record", "tau2", "index.csv"}) {
    EXPECT_NE(text.find(word), std::string::npos) << word;
  }
  EXPECT_NE(run({"record", "--out", (dir / "x").string()}, dir / "log2"), 0) << "--id is required";
  EXPECT_NE(run({"record", "--id", "Fake_1", "--out", (dir / "y").string(), "--frames", "3",
                 "--seconds", "1"},
                dir / "log3"),
            0)
      << "--frames and --seconds exclude each other";
}

TEST(RgbdtCamera, ListsTheFakeCamera) {
  const auto dir = temp_dir("list");
  ASSERT_EQ(run({"list", "--interfaces", "fake"}, dir / "log"), 0);
  EXPECT_NE(slurp(dir / "log").find("Fake_1"), std::string::npos) << slurp(dir / "log");
}

TEST(RgbdtCamera, RecordsSixteenBitFramesWithAnIndex) {
  const auto dir = temp_dir("rec");
  const fs::path out = dir / "thermal";
  ASSERT_EQ(
      run({"record", "--interfaces", "fake", "--id", "Fake_1", "--out", out.string(), "--frames",
           "30", "--pixel-format", "Mono16", "--roi", "0,0,320,256", "--rate", "100"},
          dir / "log"),
      0)
      << slurp(dir / "log");
  const auto index = rgbdt::core::read_time_index((out / "index.csv").string());
  ASSERT_EQ(index.size(), 30u);
  expect_consistent_recording(out, CV_16UC1);
  const cv::Mat first = cv::imread(index[0].file, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(first.cols, 320);
  EXPECT_EQ(first.rows, 256);
  EXPECT_NE(slurp(dir / "log").find("recorded 30 frames"), std::string::npos) << slurp(dir / "log");
  EXPECT_NE(slurp(dir / "log").find("lost 0"), std::string::npos) << slurp(dir / "log");
}

TEST(RgbdtCamera, RecordsBayerAsColourPng) {
  const auto dir = temp_dir("rec");
  const fs::path out = dir / "rgb";
  ASSERT_EQ(run({"record", "--interfaces", "fake", "--id", "Fake_1", "--out", out.string(),
                 "--frames", "3", "--pixel-format", "BayerRG8", "--rate", "50"},
                dir / "log"),
            0)
      << slurp(dir / "log");
  expect_consistent_recording(out, CV_8UC3);
}

// `--config FILE`: the record options from a YAML file, the command line over them.
TEST(RgbdtCamera, RecordsWithTheOptionsOfAConfigFile) {
  const auto dir = temp_dir("config");
  const fs::path config = dir / "thermal.yaml";
  rgbdt::test::write_text(config,
                          "record:\n  interfaces: fake\n  id: Fake_1\n  frames: 30\n"
                          "  pixel-format: Mono16\n  roi: [0, 0, 320, 256]\n  rate: 100\n");
  const fs::path out = dir / "thermal";
  ASSERT_EQ(run({"--config", config.string(), "record", "--out", out.string(), "--frames", "5"},
                dir / "log"),
            0)
      << slurp(dir / "log");
  const auto index = rgbdt::core::read_time_index((out / "index.csv").string());
  EXPECT_EQ(index.size(), 5u) << "--frames on the command line wins over the file's 30";
  expect_consistent_recording(out, CV_16UC1);
  const cv::Mat first = cv::imread(index.at(0).file, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(first.cols, 320) << "the file's roi";
  EXPECT_EQ(first.rows, 256);
}

TEST(RgbdtCamera, AnUnknownConfigKeyIsAnErrorNamingTheFileAndTheKey) {
  const auto dir = temp_dir("config");
  const fs::path config = dir / "typo.yaml";
  rgbdt::test::write_text(config, "record:\n  interfaces: fake\n  pixel-fromat: Mono16\n");
  const fs::path out = dir / "out";
  const int code = run({"--config", config.string(), "record", "--id", "Fake_1", "--out",
                        out.string(), "--frames", "3"},
                       dir / "log");
  EXPECT_GT(code, 0) << slurp(dir / "log");
  EXPECT_LT(code, 128) << slurp(dir / "log");
  const std::string text = slurp(dir / "log");
  EXPECT_NE(text.find(config.string()), std::string::npos) << text;
  EXPECT_NE(text.find("record.pixel-fromat"), std::string::npos) << text;
  EXPECT_NE(text.find("line 3"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(out)) << "nothing is recorded with a wrong file";
}

// The camera files in config/ hold only options record takes, with values a GenICam camera
// accepts: recorded from the fake camera in their pixel format (interface and id overridden).
TEST(RgbdtCamera, TheCameraFilesOfConfigRecordFromTheFakeCamera) {
  const auto dir = temp_dir("config");
  const std::vector<std::pair<std::string, int>> files = {
      {"camera_pointgrey_cm3.yaml", CV_8UC3},  // BayerRG8, demosaiced
      {"camera_flir_tau2.yaml", CV_16UC1},     // Mono16
  };
  for (const auto& [name, type] : files) {
    const fs::path config = fs::path(RGBDT_SOURCE_DIR) / "config" / name;
    const fs::path out = dir / name;
    const fs::path log = dir / (name + ".log");
    ASSERT_EQ(run({"--config", config.string(), "record", "--interfaces", "fake", "--id", "Fake_1",
                   "--out", out.string(), "--frames", "3"},
                  log),
              0)
        << name << ": " << slurp(log);
    EXPECT_NE(slurp(log).find("recorded 3 frames"), std::string::npos) << slurp(log);
    expect_consistent_recording(out, type);
  }
}

TEST(RgbdtCamera, CtrlCLeavesOnlyWholeIndexedFrames) {
  const auto dir = temp_dir("sigint");
  const fs::path out = dir / "thermal";
  const pid_t pid =
      spawn({"record", "--interfaces", "fake", "--id", "Fake_1", "--out", out.string(), "--seconds",
             "60", "--pixel-format", "Mono16", "--rate", "100"},
            dir / "log");
  // Let it write a few frames (bounded wait), then interrupt it mid-stream.
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  size_t pngs = 0;
  while (pngs < 20 && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    pngs = 0;
    if (fs::exists(out)) {
      for (const auto& e : fs::directory_iterator(out))
        pngs += e.path().extension() == ".png" ? 1 : 0;
    }
  }
  ::kill(pid, SIGINT);
  EXPECT_EQ(wait_exit(pid, std::chrono::seconds(15)), 0) << slurp(dir / "log");
  ASSERT_GE(pngs, 20u) << slurp(dir / "log");
  EXPECT_NE(slurp(dir / "log").find("stopped by signal 2"), std::string::npos)
      << slurp(dir / "log");
  expect_consistent_recording(out, CV_16UC1);
}

TEST(RgbdtCamera, Tau2SubcommandQueriesAndConfiguresTheCamera) {
  const auto dir = temp_dir("tau2");
  rgbdt::thermal_camera::Tau2PtyEmulator pty;
  ASSERT_EQ(run({"tau2", "--port", pty.path(), "--ffc", "--tlinear", "on", "--gain", "high"},
                dir / "log"),
            0)
      << slurp(dir / "log");
  const std::string text = slurp(dir / "log");
  EXPECT_NE(text.find("camera serial  123456"), std::string::npos) << text;
  EXPECT_NE(text.find("tlinear        on, 0.04 K/count"), std::string::npos) << text;
  EXPECT_NE(text.find("gain mode      high"), std::string::npos) << text;
  EXPECT_NE(text.find("fpa temp       31.2 degC"), std::string::npos) << text;
  EXPECT_EQ(pty.with_emulator([](auto& e) { return e.state().ffc_count; }), 1);
}

// Bad record arguments end with exit 1 before the camera is opened, naming the option and
// its value, and leave no recording folder behind.
TEST(RgbdtCamera, BadRecordArgumentsAreRefusedNamingTheValue) {
  const auto dir = temp_dir("bad_args");
  const fs::path file = dir / "a_file";
  std::ofstream(file) << "x";
  const fs::path recorded = dir / "recorded";
  fs::create_directories(recorded);
  std::ofstream(recorded / "index.csv") << "time_s,file\n";
  struct Case {
    std::vector<std::string> args;
    std::string expected;  // in the message
  };
  const fs::path out = dir / "out";
  const std::vector<Case> cases = {
      {{"--rate", "-5"}, "--rate -5"},
      {{"--rate", "inf"}, "--rate inf"},
      {{"--exposure", "-1"}, "--exposure -1"},
      {{"--give-up", "-2"}, "--give-up -2"},
      {{"--timeout-ms", "0"}, "--timeout-ms 0"},
      {{"--buffers", "1"}, "--buffers 1"},
      {{"--buffers", "100000"}, "--buffers 100000"},
      {{"--roi", "0,0,-4,10"}, "--roi 0,0,-4,10"},
  };
  int k = 0;
  for (const Case& c : cases) {
    std::vector<std::string> args = {"record", "--interfaces", "fake",     "--id", "Fake_1",
                                     "--out",  out.string(),   "--frames", "3"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const fs::path log = dir / ("log" + std::to_string(k++));
    EXPECT_EQ(run(args, log), 1) << c.expected << ": " << slurp(log);
    EXPECT_NE(slurp(log).find(c.expected), std::string::npos) << slurp(log);
    EXPECT_FALSE(fs::exists(out)) << c.expected << " left an output folder";
  }
  {
    const fs::path log = dir / ("log" + std::to_string(k++));
    EXPECT_EQ(
        run({"record", "--interfaces", "gige,serial", "--id", "Fake_1", "--out", out.string()},
            log),
        1)
        << slurp(log);
    EXPECT_NE(slurp(log).find("'serial'"), std::string::npos) << slurp(log);
    EXPECT_FALSE(fs::exists(out));
  }
  for (const fs::path& bad_out : {file, recorded}) {
    const fs::path log = dir / ("log" + std::to_string(k++));
    EXPECT_EQ(run({"record", "--interfaces", "fake", "--id", "Fake_1", "--out", bad_out.string(),
                   "--frames", "3"},
                  log),
              1)
        << slurp(log);
    EXPECT_NE(slurp(log).find("--out " + bad_out.string()), std::string::npos) << slurp(log);
  }
  EXPECT_EQ(slurp(file), "x") << "a file given as --out must stay as it was";
  EXPECT_EQ(fs::file_size(recorded / "index.csv"), 12U) << "an earlier recording must stay";
  const fs::path log = dir / ("log" + std::to_string(k++));
  EXPECT_EQ(run({"tau2", "--port", "/dev/null", "--baud", "-9600"}, log), 1) << slurp(log);
  EXPECT_NE(slurp(log).find("--baud -9600"), std::string::npos) << slurp(log);
}
