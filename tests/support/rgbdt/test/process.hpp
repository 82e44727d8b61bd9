#pragma once
// Running a built program from a test, with its output captured.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

extern char** environ;  // the child inherits the test's environment

namespace rgbdt::test {

/// <build>/bin/<name>, or $RGBDT_BIN_DIR/<name> (ctest sets it for every test).
inline std::string built_program(const std::string& name) {
  const char* dir = std::getenv("RGBDT_BIN_DIR");
  return (dir != nullptr ? std::string(dir) : std::string(RGBDT_BINARY_DIR) + "/bin") + "/" + name;
}

/// Starts `program args...` with stdout and stderr in `log`; returns the pid (a failed
/// start is a test failure).
inline pid_t spawn_with_log(const std::string& program, const std::vector<std::string>& args,
                            const std::filesystem::path& log) {
  std::vector<std::string> all = {program};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  EXPECT_EQ(rc, 0) << "cannot run " << argv[0];
  return pid;
}

}  // namespace rgbdt::test
