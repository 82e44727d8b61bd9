#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

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

TEST(TimeIndex, TimesAreParsedWholeField) {
  const auto dir = rgbdt::test::temp_dir("whole");
  for (const std::string bad : {"100.802xyz", "0x64", "nan", "inf", "1e999", ""}) {
    rgbdt::test::write_text(dir / "index.csv", "time_s,file\n0.0,a.png\n" + bad + ",b.png\n");
    expect_error_mentions<Error>([&] { read_time_index((dir / "index.csv").string()); },
                                 {"index.csv", "line 3", "'" + bad + "'", "finite number of seconds"});
  }
}

TEST(TimeIndex, FileColumnIsTrimmedAndHeaderOnlyIsEmpty) {
  const auto dir = rgbdt::test::temp_dir("trim");
  rgbdt::test::write_text(dir / "index.csv", "time_s,file\r\n 1.5 ,  a.png \t\r\n");
  const auto rows = read_time_index((dir / "index.csv").string());
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_DOUBLE_EQ(rows[0].time_s, 1.5);
  EXPECT_EQ(rows[0].file, (dir / "a.png").string());
  rgbdt::test::write_text(dir / "index.csv", "time_s,file\n");
  EXPECT_TRUE(read_time_index((dir / "index.csv").string()).empty());
}

TEST(TimeIndex, AnotherKindOfFileIsRefusedWithoutQuotingIt) {
  const auto dir = rgbdt::test::temp_dir("kind");
  rgbdt::test::write_text(dir / "index.csv", "SECRET first line, of something else\nmore\n");
  expect_error_mentions<Error>([&] { read_time_index((dir / "index.csv").string()); },
                               {"index.csv", "line 1", "CSV time index"});
  try {
    read_time_index((dir / "index.csv").string());
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).find("SECRET"), std::string::npos) << e.what();
  }
  expect_error_mentions<Error>([&] { read_time_index(dir.string()); }, {"folder", "CSV time index"});
}

TEST(TimeIndex, RelativeOutputFolderAndRelativeEntriesResolve) {
  // As `rgbdt_tilt_lidar assemble X.rawlog --out rel/dir`: the index and its entries are
  // given relative to the working directory.
  const auto dir = rgbdt::test::temp_dir("relative");
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  std::filesystem::create_directories("rel/dir");
  write_time_index("rel/dir/index.csv", {{0.1, "rel/dir/000.pcd"}, {0.2, "./rel/dir/sub/001.pcd"}});
  const auto rows = read_time_index("rel/dir/index.csv");
  std::ifstream in(dir / "rel/dir/index.csv");
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  std::filesystem::current_path(cwd);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].file, (dir / "rel/dir/000.pcd").string());
  EXPECT_EQ(rows[1].file, (dir / "rel/dir/sub/001.pcd").string());
  EXPECT_NE(text.find(",000.pcd\n"), std::string::npos) << text;
  EXPECT_NE(text.find(",sub/001.pcd\n"), std::string::npos) << text;
}
