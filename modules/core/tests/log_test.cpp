#include <gtest/gtest.h>

#include <vector>

#include "rgbdt/core/log.hpp"

using namespace rgbdt::core;

TEST(Log, SilentWithoutSinkAndRoutesToSink) {
  set_log_sink({});
  log_info("nobody hears this");  // must not crash or print
  std::vector<std::pair<LogLevel, std::string>> seen;
  set_log_sink([&](LogLevel l, std::string_view m) { seen.emplace_back(l, std::string(m)); });
  set_log_level(LogLevel::kInfo);
  log_debug("dropped");
  log_info("found ", 42, " points");
  log_warning("view ", 3, " rejected");
  set_log_sink({});
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].first, LogLevel::kInfo);
  EXPECT_EQ(seen[0].second, "found 42 points");
  EXPECT_EQ(seen[1].first, LogLevel::kWarning);
  EXPECT_STREQ(to_string(LogLevel::kError), "error");
}
