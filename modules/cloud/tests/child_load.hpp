#pragma once
// Runs a cloud reader in a forked child under an address-space cap, so that a crash or a
// large allocation fails the test that caused it instead of ending the test program.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "rgbdt/core/error.hpp"

namespace rgbdt::cloud::test_support {

// Exit codes of the child: what happened to the load.
constexpr int kRefusedWithPath = 0;
constexpr int kLoaded = 10;
constexpr int kRefusedWithoutPath = 11;
constexpr int kOtherException = 12;

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

/// Runs load(path) in a child limited to `cap_bytes` more address space than the test program
/// holds now, and returns how the load ended (one of the codes above, or 128 + signal).
/// The message of a refusal must contain `part` as well as the path.
template <typename Load>
int load_in_child(Load&& load, const std::filesystem::path& path, const std::string& part = "",
                  std::size_t cap_bytes = std::size_t{512} << 20) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    // ASan reserves terabytes of address space up front, so the cap applies only without it.
    if (!kAddressSanitizer) {
      std::size_t vm_now = 0;
      std::ifstream status("/proc/self/status");
      for (std::string line; std::getline(status, line);) {
        if (line.rfind("VmSize:", 0) == 0) vm_now = std::stoull(line.substr(7)) * 1024;
      }
      const rlimit limit{vm_now + cap_bytes, vm_now + cap_bytes};
      setrlimit(RLIMIT_AS, &limit);
    }
    int code = kLoaded;
    try {
      load(path.string());
    } catch (const rgbdt::core::Error& e) {
      const std::string what = e.what();
      std::fprintf(stderr, "refused: %s\n", what.c_str());
      const bool ok = what.find(path.string()) != std::string::npos &&
                      (part.empty() || what.find(part) != std::string::npos);
      code = ok ? kRefusedWithPath : kRefusedWithoutPath;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "other exception: %s\n", e.what());
      code = kOtherException;
    }
    std::fflush(nullptr);
    _exit(code);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return WEXITSTATUS(status);
}

}  // namespace rgbdt::cloud::test_support
