#include <gtest/gtest.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::core;
using rgbdt::test::expect_error_mentions;

TEST(TimeIndex, WriteThenReadRoundTrips) {
  const auto dir = rgbdt::test::temp_dir("idx");
  const std::vector<TimedFile> in = {{0.0, (dir / "rgb/000.png").string()},
                                     {0.2000001, (dir / "rgb/001.png").string()},
                                     {0.4, "/elsewhere/002.png"}};
  write_time_index((dir / "index.csv").string(), in);
  const auto out = read_time_index((dir / "index.csv").string());
  ASSERT_EQ(out.size(), 3u);
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_DOUBLE_EQ(out[i].time_s, in[i].time_s);
    EXPECT_EQ(out[i].file, in[i].file);
  }
}

TEST(TimeIndex, NearestInTime) {
  const std::vector<TimedFile> idx = {{0.0, "a"}, {0.2, "b"}, {0.4, "c"}};
  EXPECT_EQ(nearest_in_time(idx, -5), 0);
  EXPECT_EQ(nearest_in_time(idx, 0.09), 0);
  EXPECT_EQ(nearest_in_time(idx, 0.11), 1);
  EXPECT_EQ(nearest_in_time(idx, 0.35), 2);
  EXPECT_EQ(nearest_in_time(idx, 9), 2);
  EXPECT_EQ(nearest_in_time({}, 1.0), -1);
}

TEST(TimeIndex, BadRowsNameFileAndLine) {
  const auto dir = rgbdt::test::temp_dir("bad");
  rgbdt::test::write_text(dir / "index.csv", "time_s,file\n0.0,a.png\nsoon,b.png\n");
  expect_error_mentions<Error>([&] { read_time_index((dir / "index.csv").string()); },
                               {"index.csv", "line 3", "soon"});
  rgbdt::test::write_text(dir / "index.csv", "time_s,file\n1.0,a.png\n0.5,b.png\n");
  expect_error_mentions<Error>([&] { read_time_index((dir / "index.csv").string()); },
                               {"line 3", "sorted"});
  rgbdt::test::write_text(dir / "index.csv", "time_s,file\n1.0 a.png\n");
  expect_error_mentions<Error>([&] { read_time_index((dir / "index.csv").string()); },
                               {"line 2", "time_s,file"});
}
