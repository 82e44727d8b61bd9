#pragma once
// The folders a test reads and writes, fixed when the build is configured. They are compiled
// into one small library (rgbdt_test_paths, generated in the build folder) instead of being
// passed as -D flags to every test: a test's object file then does not depend on where the
// checkout lives, so ccache reuses it across clones (CI builds a fresh clone each time).
// rgbdt_add_tests force-includes this header, so RGBDT_SOURCE_DIR and the others read as
// before: `fs::path(RGBDT_BINARY_DIR) / "test_tmp"`, `std::string(RGBDT_SHARED_DATA_DIR)`.
namespace rgbdt::test {
const char* source_dir();       ///< the checkout
const char* binary_dir();       ///< the build folder
const char* shared_data_dir();  ///< ../shared/data beside the checkout (RGBDT_SHARED_DATA_DIR)
}  // namespace rgbdt::test

#define RGBDT_SOURCE_DIR (::rgbdt::test::source_dir())
#define RGBDT_BINARY_DIR (::rgbdt::test::binary_dir())
#define RGBDT_SHARED_DATA_DIR (::rgbdt::test::shared_data_dir())
