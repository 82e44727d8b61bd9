#pragma once
// Helpers shared by every module's tests (rgbdt_add_tests puts tests/support on the include
// path): per-test scratch folders under <build>/test_tmp, file writing, error checks.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace rgbdt::test {

/// <build>/test_tmp/<suite>.<test>.<name>, removed and not created: for writers that make
/// their own output folder. Under the build folder, so two builds' suites never collide.
inline std::filesystem::path temp_path(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(RGBDT_BINARY_DIR) / "test_tmp" /
                                    (std::string(info->test_suite_name()) + "." + info->name() + "." + name);
  std::filesystem::remove_all(dir);
  return dir;
}

/// temp_path(name), created empty.
inline std::filesystem::path temp_dir(const std::string& name) {
  const std::filesystem::path dir = temp_path(name);
  std::filesystem::create_directories(dir);
  return dir;
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

/// Expects `fn` to throw E whose message contains every one of `parts`.
template <typename E = std::exception, typename Fn>
void expect_error_mentions(Fn&& fn, std::initializer_list<std::string> parts) {
  try {
    fn();
    ADD_FAILURE() << "no exception thrown";
  } catch (const E& e) {
    const std::string what = e.what();
    for (const auto& part : parts) {
      EXPECT_NE(what.find(part), std::string::npos) << "message '" << what << "' lacks '" << part << "'";
    }
  }
}

}  // namespace rgbdt::test
