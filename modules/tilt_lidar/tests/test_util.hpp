#pragma once
// A fresh temporary folder per test (as in core's tests).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace rgbdt::test {

inline std::filesystem::path temp_dir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(RGBDT_BINARY_DIR) / "test_tmp" /
                                    (std::string(info->test_suite_name()) + "." + info->name() + "." + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace rgbdt::test
