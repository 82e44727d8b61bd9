#include "rgbdt/tilt_lidar/rawlog_io.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>

#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZOutputStream.h>

#include "rgbdt/core/error.hpp"
#include "stream_fixture.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::tilt_lidar {
namespace {

namespace fs = std::filesystem;

// Writes the stream in arrival order (as a recorder would).
void write_stream(RawlogWriter& w, const test::Stream& s, double scan_len) {
  std::size_t e = 0;
  for (const auto& scan : s.scans) {
    while (e < s.encoder.size() && s.encoder[e].time_s <= scan.time_s + scan_len) {
      w.write(s.encoder[e], s.counts[e]);
      ++e;
    }
    w.write(scan);
  }
  for (; e < s.encoder.size(); ++e) w.write(s.encoder[e], s.counts[e]);
}

std::vector<char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_bytes(const std::string& path, const std::vector<char>& bytes, bool gzip) {
  if (gzip) {
    mrpt::io::CFileGZOutputStream out(path);
    out.Write(bytes.data(), bytes.size());
  } else {
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
}

// A rawlog of a short stream with the beam count of its first scan record replaced by
// `count` (the field MRPT reads before resizing the scan).
std::string forged_beam_count(const fs::path& dir, std::uint32_t count, bool gzip) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 0.3);
  const std::string plain = (dir / "plain.rawlog").string();
  {
    RawlogWriter w(plain, rig);
    write_stream(w, s, rig.scanner.scan_period_s);
  }
  std::vector<char> bytes = read_bytes(plain);
  // The count follows the scanner pose object's end flag 0x88.
  const std::uint32_t beams = static_cast<std::uint32_t>(rig.scanner.beams);
  char pattern[5] = {static_cast<char>(0x88)};
  std::memcpy(pattern + 1, &beams, 4);
  const auto it = std::search(bytes.begin(), bytes.end(), pattern, pattern + 5);
  EXPECT_NE(it, bytes.end());
  std::memcpy(&*(it + 1), &count, 4);
  const std::string path = (dir / (gzip ? "forged.rawlog.gz" : "forged.rawlog")).string();
  write_bytes(path, bytes, gzip);
  return path;
}

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif

struct ChildResult {
  bool exited = false;
  int code = -1, signal = 0;
  std::string message;
};

// Runs `body` in a child under a 1 GB address-space limit; the child writes the message it
// got to a pipe and exits with the code `body` returns (or 3 on an exception).
ChildResult run_bounded(const std::function<int(std::string&)>& body) {
  int fds[2];
  EXPECT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    // ASan reserves terabytes of address space for its shadow memory up front, so the cap
    // applies only without it (the sanitizer build still checks the message and exit code).
    if (!kAddressSanitizer) {
      const rlimit lim{1ull << 30, 1ull << 30};
      setrlimit(RLIMIT_AS, &lim);
    }
    std::string msg;
    int code = 0;
    try {
      code = body(msg);
    } catch (const std::exception& e) {
      msg = e.what();
      code = 3;
    }
    (void)!write(fds[1], msg.data(), msg.size());
    _exit(code);
  }
  close(fds[1]);
  ChildResult r;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) r.message.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  r.exited = WIFEXITED(status);
  if (r.exited) r.code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  return r;
}

std::vector<TiltCloud> replay(const std::string& path, const core::TiltRig& rig, ReplayResult* result = nullptr) {
  Assembler a(rig);
  std::vector<TiltCloud> out;
  const ReplayResult r = replay_rawlog(path, a, [&out](TiltCloud&& t) { out.push_back(std::move(t)); });
  if (result) *result = r;
  return out;
}

TEST(RawlogIo, ScanAndEncoderObservationsRoundTrip) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 0.1);
  const auto obs = to_observation(s.scans[1], rig, "HOKUYO");
  EXPECT_EQ(obs->sensorLabel, "HOKUYO");
  EXPECT_EQ(obs->getScanSize(), 1081u);
  EXPECT_NEAR(obs->aperture, 270 * M_PI / 180, 1e-6);
  const Scan back = from_observation(*obs);
  EXPECT_NEAR(back.time_s, s.scans[1].time_s, 1e-6);  // Clock has 100 ns ticks
  EXPECT_EQ(back.ranges_m, s.scans[1].ranges_m);
  EXPECT_EQ(back.valid, s.scans[1].valid);
  EXPECT_EQ(back.intensity, s.scans[1].intensity);  // integral intensities survive int32

  const auto daq = to_observation(s.encoder[3], s.counts[3], "TILT_ENCODER");
  const EncoderSample e = from_observation(*daq, rig.motor);
  EXPECT_DOUBLE_EQ(e.angle_rad, rig.motor.angle_from_count(s.counts[3]));
  daq->CNTRIN_double.clear();  // angle only: AIN_double[0] is used
  EXPECT_DOUBLE_EQ(from_observation(*daq, rig.motor).angle_rad, s.encoder[3].angle_rad);
  daq->AIN_double.clear();
  EXPECT_THROW(from_observation(*daq, rig.motor), core::Error);
}

TEST(RawlogIo, ReplayedRawlogAssemblesLikeTheLiveStream) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 2.0);
  const fs::path dir = test::temp_dir("rawlog");
  const std::string path = (dir / "session.rawlog").string();
  {
    RawlogWriter w(path, rig);
    write_stream(w, s, rig.scanner.scan_period_s);
    EXPECT_EQ(w.records(), static_cast<std::int64_t>(s.scans.size() + s.encoder.size()));
  }
  Assembler live(rig);
  const auto expected = test::feed(live, s);
  ReplayResult r;
  const auto got = replay(path, rig, &r);
  EXPECT_FALSE(r.truncated) << r.error;
  EXPECT_EQ(r.scans, static_cast<std::int64_t>(s.scans.size()));
  EXPECT_EQ(r.encoder_samples, static_cast<std::int64_t>(s.encoder.size()));
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].cloud->size(), expected[k].cloud->size());
    // Timestamps pass through mrpt::Clock (100 ns ticks): per-beam phi moves < 1e-7 rad.
    for (std::size_t i = 0; i < got[k].cloud->size(); i += 7) {
      const auto& a = got[k].cloud->points[i];
      const auto& b = expected[k].cloud->points[i];
      EXPECT_NEAR(a.x, b.x, 1e-5);
      EXPECT_NEAR(a.z, b.z, 1e-5);
    }
  }
  const RawlogSummary sum = summarize_rawlog(path);
  EXPECT_EQ(sum.streams.at("HOKUYO").count, static_cast<std::int64_t>(s.scans.size()));
  EXPECT_EQ(sum.streams.at("HOKUYO").class_name, "mrpt::obs::CObservation2DRangeScan");
  EXPECT_EQ(sum.streams.at("TILT_ENCODER").count, static_cast<std::int64_t>(s.encoder.size()));
}

TEST(RawlogIo, MrptRawlogEditReadsOurFile) {
  ASSERT_TRUE(fs::exists("/usr/bin/rawlog-edit")) << "/usr/bin/rawlog-edit is missing: run scripts/install-deps (Debian mrpt-apps)";
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 0.5);
  const fs::path dir = test::temp_dir("rawlog");
  const std::string path = (dir / "session.rawlog").string();
  {
    RawlogWriter w(path, rig);
    write_stream(w, s, rig.scanner.scan_period_s);
  }
  const std::string cmd = "rawlog-edit --info -i '" + path + "' 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string text;
  char buf[512];
  while (fgets(buf, sizeof buf, p)) text += buf;
  EXPECT_EQ(pclose(p), 0) << text;
  EXPECT_NE(text.find("Observations format               : Yes"), std::string::npos) << text;
  const std::string objects = "Overall number of objects         : " + std::to_string(s.scans.size() + s.encoder.size());
  EXPECT_NE(text.find(objects), std::string::npos) << text;
  EXPECT_NE(text.find("HOKUYO"), std::string::npos) << text;
  EXPECT_NE(text.find("TILT_ENCODER"), std::string::npos) << text;
}

TEST(RawlogIo, TruncatedRawlogKeepsTheRecordsBeforeTheCut) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 2.0);
  const fs::path dir = test::temp_dir("rawlog");
  const std::string path = (dir / "session.rawlog").string();
  {
    RawlogWriter w(path, rig);
    write_stream(w, s, rig.scanner.scan_period_s);
  }
  const auto size = fs::file_size(path);
  fs::resize_file(path, size * 6 / 10 + 3);  // cut in the middle of some record
  ReplayResult r;
  const auto tilts = replay(path, rig, &r);
  EXPECT_TRUE(r.truncated);
  EXPECT_NE(r.error.find(path), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("truncated"), std::string::npos) << r.error;
  // ~60% of the scans survive: tilts up to ~1.2 s (reversals 0.3, 0.9 s).
  EXPECT_GT(r.scans, static_cast<std::int64_t>(s.scans.size()) / 2);
  EXPECT_LT(r.scans, static_cast<std::int64_t>(s.scans.size()) * 7 / 10);
  EXPECT_GE(tilts.size(), 2u);

  RawlogReader reader(path);
  std::int64_t n = 0;
  while (reader.next()) ++n;
  EXPECT_TRUE(reader.truncated());
  EXPECT_EQ(n, r.scans + r.encoder_samples);
}

TEST(RawlogIo, MissingFileNamesThePath) {
  try {
    RawlogReader reader("/nonexistent/x.rawlog");
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/x.rawlog"), std::string::npos);
  }
}

// Real MRPT rawlogs (shared/data/mrpt, BSD-3): counts and time spans as rawlog-edit --info
// reports them.
TEST(RawlogIo, ReadsRealMrptRawlogs) {
  const fs::path data = fs::path(RGBDT_SHARED_DATA_DIR) / "mrpt" / "datasets";
  const fs::path sena = data / "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog";
  const fs::path demo = data / "localization_demo.rawlog";
  const fs::path rot = data / "rot_scan_2d.rawlog";
  for (const auto& p : {sena, demo, rot}) ASSERT_TRUE(fs::exists(p)) << "missing test data " << p;

  // Actions/sensory-frame format, 449 objects. rawlog-edit --list-timestamps lists 224
  // scans from 1137834225.973760 on, leaving out the first frame (...225.713386); every
  // sensory frame's observations are delivered here, 225 in all.
  const RawlogSummary s = summarize_rawlog(sena.string());
  EXPECT_FALSE(s.truncated) << s.error;
  EXPECT_EQ(s.observations, 225);
  ASSERT_EQ(s.streams.size(), 1u);
  const auto& st = s.streams.begin()->second;
  EXPECT_EQ(st.class_name, "mrpt::obs::CObservation2DRangeScan");
  EXPECT_NEAR(st.first_time_s, 1137834225.713386, 1e-5);
  EXPECT_NEAR(st.last_time_s, 1137834284.788331, 1e-5);

  EXPECT_EQ(summarize_rawlog(demo.string()).observations, 37);
  // Observations format holding one CObservationRotatingScan (a class of mrpt-maps).
  RawlogReader rreader(rot.string());
  auto robs = rreader.next();
  ASSERT_TRUE(robs) << rreader.error();
  EXPECT_STREQ(robs->GetRuntimeClass()->className, "mrpt::obs::CObservationRotatingScan");
  EXPECT_NEAR(mrpt::Clock::toDouble(robs->timestamp), 1137772793.094853, 1e-5);
  EXPECT_FALSE(rreader.next());
  EXPECT_FALSE(rreader.truncated()) << rreader.error();

  // A 2D scan from the localization demo: convertible to our Scan, sane ranges.
  RawlogReader reader(demo.string());
  auto obs = reader.next();
  ASSERT_TRUE(obs);
  const auto* scan = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(obs.get());
  ASSERT_NE(scan, nullptr);
  const Scan sc = from_observation(*scan);
  EXPECT_GT(sc.ranges_m.size(), 100u);
  int valid = 0;
  for (std::size_t i = 0; i < sc.ranges_m.size(); ++i) {
    if (!sc.valid[i]) continue;
    ++valid;
    EXPECT_GT(sc.ranges_m[i], 0.0f);
    EXPECT_LT(sc.ranges_m[i], scan->maxRange + 1e-3f);
  }
  EXPECT_GT(valid, 50);
}

// A scan record claiming ~4 G beams: reading stops at that record with a message naming
// the file and the count, in bounded memory (1 GB address space), plain and gzip.
TEST(RawlogIo, ForgedBeamCountIsRefusedInBoundedMemory) {
  const fs::path dir = test::temp_dir("rawlog");
  for (const bool gzip : {false, true}) {
    const std::string path = forged_beam_count(dir, 0xFFFFFFF0u, gzip);
    const ChildResult r = run_bounded([&](std::string& msg) {
      const RawlogSummary s = summarize_rawlog(path);
      msg = s.error;
      return s.truncated ? 2 : 0;
    });
    ASSERT_TRUE(r.exited) << "reader died of signal " << r.signal << " on " << path;
    EXPECT_EQ(r.code, 2) << r.message;
    EXPECT_NE(r.message.find(path), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("4294967280 beams"), std::string::npos) << r.message;

    const ChildResult rr = run_bounded([&](std::string& msg) {
      Assembler a(test::test_rig());
      const ReplayResult res = replay_rawlog(path, a, [](TiltCloud&&) {});
      msg = res.error;
      return res.truncated ? 2 : 0;
    });
    ASSERT_TRUE(rr.exited) << "replay died of signal " << rr.signal << " on " << path;
    EXPECT_EQ(rr.code, 2) << rr.message;
  }
}

// A count within the beam limit but beyond the bytes left in the file is refused before
// anything is allocated for it: the record ends early, reported as such.
TEST(RawlogIo, CountLargerThanTheFileIsRefused) {
  const fs::path dir = test::temp_dir("rawlog");
  const std::uint32_t count = 19999;
  const std::string path = forged_beam_count(dir, count, false);
  // Cut the file 2000 bytes after the count: far fewer than 19999 beams' worth.
  const std::vector<char> bytes = read_bytes(path);
  char pattern[5] = {static_cast<char>(0x88)};
  std::memcpy(pattern + 1, &count, 4);
  const auto at = std::search(bytes.begin(), bytes.end(), pattern, pattern + 5) - bytes.begin();
  ASSERT_LT(at + 2005, static_cast<std::ptrdiff_t>(bytes.size()));
  fs::resize_file(path, static_cast<std::uintmax_t>(at + 2005));
  RawlogReader reader(path);
  while (reader.next()) {
  }
  EXPECT_TRUE(reader.truncated());
  EXPECT_NE(reader.error().find("bytes early"), std::string::npos) << reader.error();
}

TEST(RawlogIo, GzipOfGarbageAndEmptyFilesAreNotRawlogs) {
  const fs::path dir = test::temp_dir("rawlog");
  std::mt19937 rng(7);
  std::vector<char> garbage(20000);
  for (auto& c : garbage) c = static_cast<char>(rng());
  const std::string gz = (dir / "garbage.rawlog").string();
  write_bytes(gz, garbage, true);
  const std::string empty = (dir / "empty.rawlog").string();
  write_bytes(empty, {}, false);
  for (const auto& path : {gz, empty}) {
    try {
      summarize_rawlog(path);
      FAIL() << path << " read as a rawlog";
    } catch (const core::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_TRUE(what.find("not an MRPT rawlog") != std::string::npos ||
                  what.find("holds no observations") != std::string::npos)
          << what;
    }
    Assembler a(test::test_rig());
    EXPECT_THROW(replay_rawlog(path, a, [](TiltCloud&&) {}), core::Error) << path;
  }
}

TEST(RawlogIo, NonFiniteAndNegativeRangesAreNotValidBeams) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 0.1);
  auto obs = to_observation(s.scans[0], rig, "HOKUYO");
  const float bad[] = {std::nanf(""), -1.0f, std::numeric_limits<float>::infinity()};
  for (std::size_t i = 0; i < 3; ++i) {
    obs->setScanRange(i, bad[i]);
    obs->setScanRangeValidity(i, true);
  }
  const Scan sc = from_observation(*obs);
  for (std::size_t k = 0; k < sc.ranges_m.size(); ++k) {
    const std::size_t i = k;  // rightToLeft: beam order unchanged
    if (i < 3) {
      EXPECT_EQ(sc.valid[k], 0) << "beam " << i << " range " << bad[i];
      EXPECT_TRUE(std::isfinite(sc.ranges_m[k]));
    }
  }
}

TEST(RawlogIo, EncoderTimeGoingBackOrNotFiniteStopsReplayNamingTheRecord) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 1.0);
  const fs::path dir = test::temp_dir("rawlog");
  // A sample stamped before the previous one, then one whose angle is NaN.
  for (const bool nan_angle : {false, true}) {
    const std::string path = (dir / "back.rawlog").string();
    const std::size_t half = s.encoder.size() / 2;
    {
      RawlogWriter w(path, rig);
      for (std::size_t e = 0; e < half; ++e) w.write(s.encoder[e], s.counts[e]);
      if (nan_angle) {
        auto daq = to_observation(s.encoder[half], s.counts[half], "TILT_ENCODER");
        daq->CNTRIN_double.clear();
        daq->AIN_double = {std::nan("")};
        w.write(*daq);
      } else {
        EncoderSample back = s.encoder[half];
        back.time_s = s.encoder[half / 2].time_s;
        w.write(back, s.counts[half]);
      }
      for (std::size_t e = half + 1; e < s.encoder.size(); ++e) w.write(s.encoder[e], s.counts[e]);
    }
    ReplayResult r;
    replay(path, rig, &r);
    EXPECT_TRUE(r.truncated) << "nan angle " << nan_angle;
    EXPECT_NE(r.error.find(path), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("record " + std::to_string(half) + " "), std::string::npos) << r.error;
    EXPECT_NE(r.error.find(nan_angle ? "expected finite" : "expected non-decreasing"), std::string::npos) << r.error;
    EXPECT_EQ(r.encoder_samples, static_cast<std::int64_t>(half)) << r.error;
  }
}

TEST(RawlogIo, WriterRefusesNonFiniteTimes) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 0.1);
  const fs::path dir = test::temp_dir("rawlog");
  RawlogWriter w((dir / "w.rawlog").string(), rig);
  EncoderSample e = s.encoder[0];
  e.time_s = std::nan("");
  EXPECT_THROW(w.write(e, s.counts[0]), std::invalid_argument);
  Scan sc = s.scans[0];
  sc.time_s = std::numeric_limits<double>::infinity();
  EXPECT_THROW(w.write(sc), std::invalid_argument);
  EXPECT_EQ(w.records(), 0);
}

TEST(RawlogIo, StopEndsReplayWithoutTheUnfinishedTilt) {
  const auto rig = test::test_rig();
  const auto s = test::make_stream(rig, test::MotionProfile{}, 2.0);
  const fs::path dir = test::temp_dir("rawlog");
  const std::string path = (dir / "session.rawlog").string();
  {
    RawlogWriter w(path, rig);
    write_stream(w, s, rig.scanner.scan_period_s);
  }
  Assembler a(rig);
  int tilts = 0;
  const ReplayResult r = replay_rawlog(path, a, [&](TiltCloud&&) { ++tilts; }, {}, [&] { return tilts >= 1; });
  EXPECT_TRUE(r.interrupted);
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(tilts, 1);
  EXPECT_LT(r.scans, static_cast<std::int64_t>(s.scans.size()));
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
