// GenicamCamera over the real GigE Vision network path: Aravis's arv-fake-gv-camera-0.8
// (Debian aravis-tools) serves GVCP/GVSP on 127.0.0.1 only. The camera process is killed
// mid-stream and restarted to check that the driver reports the loss and recovers. Most
// tests open it by address, so no traffic leaves the host; the ones that open it by the id
// list_devices() shows (GigeDiscoveryOn) send one GigE discovery broadcast on each IPv4
// interface. ctest runs these tests one at a time (RESOURCE_LOCK): the fake camera needs
// UDP port 3956 on 127.0.0.1.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include "rgbdt/core/time_index.hpp"

#include "rgbdt/core/error.hpp"
#include "rgbdt/test/process.hpp"
#include "rgbdt/thermal_camera/genicam_camera.hpp"

#include <opencv2/imgcodecs.hpp>

extern char** environ;

using namespace rgbdt::thermal_camera;
using Clock = std::chrono::steady_clock;

// No broadcast discovery: the cameras here are opened by address on loopback.
const bool kInterfacesSelected = [] {
  select_interfaces({/*gige=*/false, /*usb3=*/false, /*fake=*/false});
  return true;
}();

namespace {

constexpr const char* kFakeGvCamera = "arv-fake-gv-camera-0.8";

/// One arv-fake-gv-camera process on 127.0.0.1, killed in the destructor.
class FakeGvCamera {
 public:
  explicit FakeGvCamera(const std::string& serial) : serial_(serial) {}
  ~FakeGvCamera() { kill_now(); }

  void start() {
    const char* argv[] = {kFakeGvCamera, "-i", "127.0.0.1", "-s", serial_.c_str(), nullptr};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    const int rc = posix_spawnp(&pid_, kFakeGvCamera, &actions, nullptr,
                                const_cast<char* const*>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    ASSERT_EQ(rc, 0) << "cannot start " << kFakeGvCamera << " (Debian package aravis-tools)";
  }

  void kill_now() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

  // By address: opened from the loopback interface without broadcast discovery.
  std::string device_id() const { return "127.0.0.1"; }

 private:
  std::string serial_;
  pid_t pid_ = -1;
};

// Opens the camera, retrying while the freshly spawned process comes up (bounded).
std::unique_ptr<GenicamCamera> open_when_ready(const std::string& id, const GenicamOptions& o) {
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  while (true) {
    try {
      return std::make_unique<GenicamCamera>(id, o);
    } catch (const rgbdt::core::Error&) {
      if (Clock::now() > deadline) throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  }
}

GenicamOptions fast_options() {
  GenicamOptions o;
  o.pixel_format = "Mono8";
  o.region = Region{0, 0, 320, 240};  // small frames keep loopback traffic low
  o.frame_rate_hz = 50.0;
  o.timeout_ms = 300;
  o.timeouts_before_reconnect = 2;
  o.reconnect_interval_ms = 300;
  return o;
}

std::string unique_serial(const char* tag) {
  return std::string(tag) + std::to_string(::getpid() % 100000);
}

/// GigE discovery on for one test (list_devices() and opening by id need it), back to this
/// file's default (every interface off) at the end.
class GigeDiscoveryOn {
 public:
  GigeDiscoveryOn() { select_interfaces({/*gige=*/true, /*usb3=*/false, /*fake=*/false}); }
  ~GigeDiscoveryOn() { select_interfaces({/*gige=*/false, /*usb3=*/false, /*fake=*/false}); }
  GigeDiscoveryOn(const GigeDiscoveryOn&) = delete;
  GigeDiscoveryOn& operator=(const GigeDiscoveryOn&) = delete;
};

// The fake camera with this serial as list_devices() shows it, once the freshly spawned
// process answers discovery (bounded); nullopt when it never shows up.
std::optional<DeviceInfo> listed_camera(const std::string& serial) {
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  while (Clock::now() < deadline) {
    for (const auto& d : list_devices()) {
      if (d.serial == serial) return d;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return std::nullopt;
}

}  // namespace

TEST(GenicamGige, StreamsOverLoopback) {
  FakeGvCamera fake(unique_serial("S"));
  fake.start();
  auto camera = open_when_ready(fake.device_id(), fast_options());
  EXPECT_EQ(camera->info().protocol, "GigEVision");
  camera->start();
  int frames = 0;
  for (int i = 0; i < 100 && frames < 50; ++i) {
    if (camera->grab().status == GrabStatus::kFrame) ++frames;
  }
  EXPECT_EQ(frames, 50);
  const auto stats = camera->statistics();
  // Loopback with the fake's default 0 packet-loss ratio: every frame arrives whole.
  EXPECT_EQ(stats.frames_lost, 0u);
  EXPECT_EQ(stats.frames_incomplete, 0u);
}

// Issue #30: discovery also hears the fake camera on 127.0.0.1 through the Ethernet
// interface's socket; opening by id must still stream over loopback.
TEST(GenicamGige, OpensByTheListedIdAndStreams) {
  const std::string serial = unique_serial("L");
  FakeGvCamera fake(serial);
  fake.start();
  GigeDiscoveryOn discovery;
  const auto listed = listed_camera(serial);
  ASSERT_TRUE(listed) << "the fake camera " << serial << " is not listed";
  EXPECT_EQ(listed->protocol, "GigEVision");
  EXPECT_EQ(listed->address, "127.0.0.1");
  ASSERT_NE(listed->id, listed->address);
  ASSERT_FALSE(listed->id.empty());

  GenicamCamera camera(listed->id, fast_options());
  EXPECT_EQ(camera.device_id(), listed->id);
  EXPECT_EQ(camera.info().protocol, "GigEVision");
  EXPECT_EQ(camera.info().serial, serial);
  camera.start();
  constexpr int kFrames = 30;
  int frames = 0;
  for (int i = 0; i < 3 * kFrames && frames < kFrames; ++i) {
    const GrabResult r = camera.grab();
    if (r.status != GrabStatus::kFrame) continue;
    ++frames;
    EXPECT_EQ(r.frame.image.cols, 320);
    EXPECT_EQ(r.frame.image.rows, 240);
    EXPECT_EQ(r.frame.image.type(), CV_8UC1);
    EXPECT_EQ(r.frame.pixel_format, "Mono8");
  }
  EXPECT_EQ(frames, kFrames) << camera.statistics().timeouts << " timeouts";
  EXPECT_EQ(camera.statistics().frames_incomplete, 0u);
}

TEST(GenicamGige, AnUnknownIdFailsNamingItAndTheListedIds) {
  const std::string serial = unique_serial("U");
  FakeGvCamera fake(serial);
  fake.start();
  GigeDiscoveryOn discovery;
  const auto listed = listed_camera(serial);
  ASSERT_TRUE(listed) << "the fake camera " << serial << " is not listed";
  const std::string unknown = "No-Such-Camera-" + serial;
  try {
    GenicamCamera camera(unknown, fast_options());
    ADD_FAILURE() << "opened a camera that does not exist";
  } catch (const rgbdt::core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(unknown), std::string::npos) << what;
    EXPECT_NE(what.find("no camera has this id"), std::string::npos) << what;
    EXPECT_NE(what.find("'" + listed->id + "'"), std::string::npos) << what;
  }
}

TEST(GenicamGige, ReportsAKilledCameraAndRecoversWhenItIsBack) {
  FakeGvCamera fake(unique_serial("K"));
  fake.start();
  auto camera = open_when_ready(fake.device_id(), fast_options());
  camera->start();
  int frames_before = 0;
  for (int i = 0; i < 60 && frames_before < 20; ++i) {
    if (camera->grab().status == GrabStatus::kFrame) ++frames_before;
  }
  ASSERT_EQ(frames_before, 20);

  fake.kill_now();
  // Bounded: each grab() waits at most timeout_ms plus one register read (GVCP timeouts
  // and retries, ~3 s on Aravis 0.8) before the device is declared lost.
  GrabResult r;
  const auto lost_deadline = Clock::now() + std::chrono::seconds(20);
  while (Clock::now() < lost_deadline) {
    r = camera->grab();
    if (r.status == GrabStatus::kDisconnected) break;
  }
  ASSERT_EQ(r.status, GrabStatus::kDisconnected) << r.message;
  EXPECT_NE(r.message.find(fake.device_id()), std::string::npos) << r.message;
  EXPECT_FALSE(camera->streaming());

  // While it is away, grab() keeps reporting the loss, promptly, and tries to reopen.
  bool tried_to_reopen = false;
  const auto away_deadline = Clock::now() + std::chrono::seconds(20);
  while (!tried_to_reopen && Clock::now() < away_deadline) {
    const auto t0 = Clock::now();
    r = camera->grab();
    const double took_s = std::chrono::duration<double>(Clock::now() - t0).count();
    ASSERT_EQ(r.status, GrabStatus::kDisconnected) << r.message;
    // One reopen attempt against a dead address waits for Aravis's GVCP timeouts and
    // retries (~2.5 s measured); 5 s leaves room for a loaded machine.
    EXPECT_LT(took_s, 5.0) << r.message;
    tried_to_reopen = r.message.find("reconnect attempt") != std::string::npos;
  }
  EXPECT_TRUE(tried_to_reopen) << r.message;

  fake.start();
  const auto back_deadline = Clock::now() + std::chrono::seconds(30);
  while (Clock::now() < back_deadline) {
    r = camera->grab();
    if (r.status == GrabStatus::kReconnected) break;
  }
  ASSERT_EQ(r.status, GrabStatus::kReconnected) << r.message;
  EXPECT_TRUE(camera->streaming());
  int frames_after = 0;
  for (int i = 0; i < 60 && frames_after < 20; ++i) {
    if (camera->grab().status == GrabStatus::kFrame) ++frames_after;
  }
  EXPECT_EQ(frames_after, 20);
  const auto stats = camera->statistics();
  EXPECT_EQ(stats.disconnects, 1u);
  EXPECT_EQ(stats.reconnects, 1u);
  EXPECT_EQ(stats.frames_completed, 40u);
}

namespace {

namespace fs = std::filesystem;

pid_t spawn_recorder(const std::vector<std::string>& args, const fs::path& log) {
  return rgbdt::test::spawn_with_log(rgbdt::test::built_program("rgbdt_camera"), args, log);
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

size_t count_png(const fs::path& dir) {
  size_t n = 0;
  if (!fs::exists(dir)) return 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".png" ? 1 : 0;
  return n;
}

// Polls `done` every 50 ms until it holds or `limit` passes.
template <typename Pred>
bool wait_for(Pred done, std::chrono::seconds limit) {
  const auto deadline = Clock::now() + limit;
  while (!done()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

void expect_whole_indexed_frames(const fs::path& out) {
  const auto index = rgbdt::core::read_time_index((out / "index.csv").string());
  EXPECT_EQ(count_png(out), index.size()) << "PNG files and index rows differ";
  for (const auto& e : index) {
    const cv::Mat image = cv::imread(e.file, cv::IMREAD_UNCHANGED);
    EXPECT_EQ(image.type(), CV_16UC1) << e.file;
  }
}

}  // namespace

TEST(GenicamGige, RecorderKeepsWholeIndexedFramesAcrossACameraLoss) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "GenicamGige.RecorderAcrossLoss";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path out = dir / "thermal", log = dir / "log";
  FakeGvCamera fake(unique_serial("R"));
  fake.start();
  open_when_ready(fake.device_id(), fast_options());  // up and answering

  const pid_t pid =
      spawn_recorder({"record", "--interfaces", "none", "--id", fake.device_id(), "--out",
                      out.string(), "--seconds", "120", "--pixel-format", "Mono16", "--roi",
                      "0,0,320,240", "--rate", "50", "--timeout-ms", "300", "--give-up", "60"},
                     log);
  ASSERT_TRUE(wait_for([&] { return count_png(out) >= 20; }, std::chrono::seconds(20)))
      << slurp(log);

  fake.kill_now();
  ASSERT_TRUE(wait_for([&] { return slurp(log).find("lost (") != std::string::npos; },
                       std::chrono::seconds(30)))
      << slurp(log);
  // While the camera is away the recording on disk is already complete and indexed.
  const size_t frames_before = count_png(out);
  expect_whole_indexed_frames(out);

  fake.start();
  ASSERT_TRUE(
      wait_for([&] { return count_png(out) >= frames_before + 20; }, std::chrono::seconds(40)))
      << slurp(log);
  ::kill(pid, SIGINT);
  int status = 0;
  ASSERT_TRUE(
      wait_for([&] { return ::waitpid(pid, &status, WNOHANG) == pid; }, std::chrono::seconds(20)));
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(log);
  const std::string text = slurp(log);
  EXPECT_NE(text.find("reconnected"), std::string::npos) << text;
  EXPECT_NE(text.find("disconnects 1, reconnects 1"), std::string::npos) << text;
  expect_whole_indexed_frames(out);
}

// Issue #30 end to end: `rgbdt_camera record` in a fresh process with the id `rgbdt_camera
// list` prints (before the fix Aravis opened it from the Ethernet interface and recorded
// nothing).
TEST(GenicamGige, RecorderRecordsByTheIdListPrints) {
  const fs::path dir = fs::path(RGBDT_BINARY_DIR) / "test_tmp" / "GenicamGige.RecordByListedId";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path out = dir / "thermal", log = dir / "log";
  const std::string serial = unique_serial("I");
  FakeGvCamera fake(serial);
  fake.start();

  // `list` prints "ID PROTOCOL VENDOR MODEL SERIAL ADDRESS" rows.
  std::string id;
  const auto list_deadline = Clock::now() + std::chrono::seconds(20);
  while (id.empty() && Clock::now() < list_deadline) {
    const pid_t pid = spawn_recorder({"list", "--interfaces", "gige"}, log);
    int status = 0;
    ASSERT_TRUE(wait_for([&] { return ::waitpid(pid, &status, WNOHANG) == pid; },
                         std::chrono::seconds(20)));
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(log);
    std::istringstream rows(slurp(log));
    for (std::string row; std::getline(rows, row);) {
      std::istringstream fields(row);
      std::string first, protocol, vendor, model, listed_serial;
      fields >> first >> protocol >> vendor >> model >> listed_serial;
      if (listed_serial == serial) id = first;
    }
  }
  ASSERT_FALSE(id.empty()) << "the fake camera " << serial << " is not listed:\n" << slurp(log);
  ASSERT_NE(id, "127.0.0.1");

  constexpr size_t kFrames = 30;
  const pid_t pid = spawn_recorder(
      {"record", "--interfaces", "gige", "--id", id, "--frames", std::to_string(kFrames), "--out",
       out.string(), "--pixel-format", "Mono16", "--roi", "0,0,320,240", "--rate", "50",
       "--timeout-ms", "300", "--give-up", "10"},
      log);
  int status = 0;
  if (!wait_for([&] { return ::waitpid(pid, &status, WNOHANG) == pid; },
                std::chrono::seconds(30))) {
    ::kill(pid, SIGINT);
    if (!wait_for([&] { return ::waitpid(pid, &status, WNOHANG) == pid; },
                  std::chrono::seconds(20))) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
    }
    FAIL() << "record --id " << id << " did not finish " << kFrames << " frames in 30 s:\n"
           << slurp(log);
  }
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(log);
  const auto index = rgbdt::core::read_time_index((out / "index.csv").string());
  EXPECT_EQ(index.size(), kFrames) << slurp(log);
  expect_whole_indexed_frames(out);
  for (const auto& e : index) {
    const cv::Mat image = cv::imread(e.file, cv::IMREAD_UNCHANGED);
    EXPECT_EQ(image.cols, 320) << e.file;
    EXPECT_EQ(image.rows, 240) << e.file;
  }
}
