// rgbdt_coloring_error on bad input: every numeric option and the setup session are checked
// before any work, and the error names the option or file, the value and what was expected.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "rgbdt/test/process.hpp"
#include "rgbdt/test/test_util.hpp"

namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Runs the app; returns its exit code (128 + signal when a signal ended it).
int run(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = rgbdt::test::spawn_with_log(rgbdt::test::built_program("rgbdt_coloring_error"), args, log);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

TEST(ColoringErrorApp, NonFiniteOrNegativeNumbersAreRefusedNamingTheOption) {
  const fs::path dir = rgbdt::test::temp_dir("numbers");
  struct Case {
    std::vector<std::string> args;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {{"--fx", "1335", "--lidar-noise", "nan"}, "--lidar-noise nan"},
      {{"--fx", "inf"}, "--fx inf"},
      {{"--fx", "1335", "--lidar-noise", "-0.02"}, "--lidar-noise -0.02"},
      {{"--fx", "1335", "--tilt-sigma-deg", "-1"}, "--tilt-sigma-deg -1"},
      // An infinite depth range would fill memory with table rows; a tiny step likewise.
      {{"--calib", dir.string(), "--intrinsics", "x.yaml", "--report", dir.string(), "--depth-max", "inf"},
       "--depth-max inf"},
      {{"--calib", dir.string(), "--intrinsics", "x.yaml", "--report", dir.string(), "--depth-step", "1e-9"},
       "--depth-step 1e-09"},
      {{"--calib", dir.string(), "--intrinsics", "x.yaml", "--report", dir.string(), "--intrinsics-sigma", "1",
        "1", "nan", "1"},
       "--intrinsics-sigma nan"},
      {{"--calib", dir.string(), "--intrinsics", "x.yaml", "--report", dir.string(), "--monte-carlo", "-5"},
       "--monte-carlo -5"},
  };
  int k = 0;
  for (const Case& c : cases) {
    const fs::path log = dir / ("log" + std::to_string(k++));
    EXPECT_EQ(run(c.args, log), 1) << c.expected << ": " << slurp(log);
    EXPECT_NE(slurp(log).find(c.expected), std::string::npos) << slurp(log);
  }
  EXPECT_FALSE(fs::exists(dir / "coloring_error.md")) << "nothing may be written on bad options";
}

TEST(ColoringErrorApp, CameraNameThatIsNoFileNameIsRefusedNamingTheKey) {
  const fs::path dir = rgbdt::test::temp_dir("camera_name");
  rgbdt::test::write_text(dir / "session" / "session.yaml",
                          "cameras:\n"
                          "  ../../escape:\n"
                          "    intrinsics: rgb.yaml\n"
                          "views:\n"
                          "  - cloud: v0.pcd\n"
                          "    images: {../../escape: v0.png}\n");
  fs::create_directories(dir / "calib");
  const fs::path log = dir / "log";
  EXPECT_EQ(run({"--setup", (dir / "session").string(), "--calib", (dir / "calib").string()}, log), 1) << slurp(log);
  const std::string text = slurp(log);
  EXPECT_NE(text.find((dir / "session" / "session.yaml").string()), std::string::npos) << text;
  EXPECT_NE(text.find("cameras.../../escape"), std::string::npos) << text;
  EXPECT_NE(text.find("[A-Za-z0-9_-]"), std::string::npos) << text;
}
