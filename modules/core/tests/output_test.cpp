// Atomic outputs, whole-field number parsing.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/parse.hpp"

namespace fs = std::filesystem;
using namespace rgbdt::core;

namespace {
fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("rgbdt_output_test_" + name + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
int entries(const fs::path& d) {
  int n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(d)) ++n;
  return n;
}
}  // namespace

TEST(WriteFileAtomic, WritesWholeFileAndLeavesNoTemporary) {
  const fs::path d = fresh_dir("whole");
  write_file_atomic((d / "a.json").string(), "{\"x\": 1}\n");
  EXPECT_EQ(slurp(d / "a.json"), "{\"x\": 1}\n");
  write_file_atomic((d / "a.json").string(), "second");
  EXPECT_EQ(slurp(d / "a.json"), "second");
  EXPECT_EQ(entries(d), 1);
  fs::remove_all(d);
}

TEST(WriteFileAtomic, MissingFolderNamesThePath) {
  const fs::path d = fresh_dir("missing");
  const std::string target = (d / "no" / "such" / "out.csv").string();
  try {
    write_file_atomic(target, "x");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(target), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

TEST(TempOutput, EmptyResultIsAnErrorAndLeavesNothing) {
  const fs::path d = fresh_dir("full");
  {
    TempOutput out((d / "map.bt").string());
    // The library "wrote" nothing, as a writer on a full disk leaves an empty file.
    std::ofstream(out.temp_path()).close();
    EXPECT_THROW(out.commit(), Error);
  }
  EXPECT_EQ(entries(d), 0);
  fs::remove_all(d);
}

TEST(TempOutput, UncommittedTemporaryIsRemoved) {
  const fs::path d = fresh_dir("uncommitted");
  {
    TempOutput out((d / "map.ply").string());
    EXPECT_EQ(fs::path(out.temp_path()).extension(), ".ply");
    std::ofstream(out.temp_path()) << "ply\n";
  }
  EXPECT_EQ(entries(d), 0);
  {
    TempOutput out((d / "map.ply").string());
    std::ofstream(out.temp_path()) << "ply\n";
    out.commit();
  }
  EXPECT_EQ(slurp(d / "map.ply"), "ply\n");
  EXPECT_EQ(entries(d), 1);
  fs::remove_all(d);
}

// A second Ctrl-C ends the process at once; the temporary of an output still being
// written must not stay behind, while files already committed stay whole.
TEST(TempOutput, SecondInterruptRemovesTheTemporaryAndKeepsCommittedFiles) {
  const fs::path d = fresh_dir("twice");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    install_interrupt_handler();
    std::raise(SIGINT);  // the first one only raises the flag
    if (!interrupted()) ::_exit(3);
    TempOutput done((d / "trajectory.csv").string());
    std::ofstream(done.temp_path()) << "time_s\n";
    done.commit();
    TempOutput writing((d / "map.ply").string());
    std::ofstream(writing.temp_path()) << "ply\n";  // a writer is half-way through
    std::raise(SIGINT);                              // the second one ends the process
    ::_exit(4);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "exit status " << status;
  EXPECT_EQ(WTERMSIG(status), SIGINT);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(d)) names.push_back(e.path().filename().string());
  ASSERT_EQ(names.size(), 1U) << "left: " << ::testing::PrintToString(names);
  EXPECT_EQ(names[0], "trajectory.csv");
  EXPECT_EQ(slurp(d / "trajectory.csv"), "time_s\n");
  fs::remove_all(d);
}

TEST(ParseFiniteDouble, AcceptsOnlyWholeDecimalFields) {
  EXPECT_EQ(parse_finite_double("100.802"), 100.802);
  EXPECT_EQ(parse_finite_double(" -1.5e3 "), -1500.0);
  EXPECT_EQ(parse_finite_double("7"), 7.0);
  EXPECT_EQ(parse_finite_double(".5"), 0.5);
  for (const char* bad : {"100.802xyz", "0x64", "", " ", "nan", "inf", "-inf", "1e400", "1e",
                          "+", ".", "1..2", "1,5", "--1"}) {
    EXPECT_FALSE(parse_finite_double(bad).has_value()) << "'" << bad << "'";
  }
}

TEST(ParseInteger, RangeAndWholeField) {
  EXPECT_EQ(parse_integer("42", 0, 100), 42);
  EXPECT_FALSE(parse_integer("101", 0, 100).has_value());
  EXPECT_FALSE(parse_integer("4.2", 0, 100).has_value());
  EXPECT_FALSE(parse_integer("0x10", 0, 100).has_value());
  EXPECT_FALSE(parse_integer("99999999999999999999999", 0, 100).has_value());
}
