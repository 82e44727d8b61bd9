// rgbdt_import's speed beside `cp` of the same file (issue #31: "import at disk speed: a 2 GB
// bag in under 60 s on one core, memory independent of the bag's size").
//
// Writes a ROS 2 MCAP with the vendored mcap library's McapWriter: sensor_msgs/PointCloud2 at
// 10 Hz (--points points of x y z intensity float32, 16 bytes a point), a thermal mono16 Image
// (640x512) at 10 Hz and an rgb8 Image (640x480) at 5 Hz, until the file reaches --size-mb.
// Then it times `cp` of the bag and `rgbdt_import --kind mapping` on it (child processes; wall
// time, the child's user+system CPU time and peak RSS from wait4) and prints a table: MB/s of
// each, their ratio, and the import's peak memory; and the import of the clouds alone (the rest
// of the import's time is what the camera frames cost).
//
//   import_bench                 # ~500 MB
//   import_bench --size-mb 2048  # the 2 GB bag
//   taskset -c 1 import_bench    # one core, as the target states
//
// Both read the bag just written, so from the page cache when it fits in memory: the ratio
// compares the import's work with a plain copy of the same bytes, not disk speeds.
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <mcap/writer.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "cdr_writer.hpp"
#include "rgbdt/bag/messages.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using rgbdt::bag::CompressedImage;
using rgbdt::bag::Image;
using rgbdt::bag::PointCloud2;
using rgbdt::bag::PointField;

constexpr std::int64_t kT0 = 1700000000000000000;  // [ns]

rgbdt::bag::Time stamp(std::int64_t ns) {
  return {std::int32_t(ns / 1000000000), std::uint32_t(ns % 1000000000)};
}

// A rotating LIDAR's sweep: `n` points on rings, ranges varying with the cloud index.
PointCloud2 cloud(std::uint32_t n, int index, std::int64_t ns) {
  PointCloud2 c;
  c.header.stamp = stamp(ns);
  c.header.frame_id = "lidar";
  c.height = 1;
  c.width = n;
  c.fields = {{"x", 0, PointField::kFloat32, 1},
              {"y", 4, PointField::kFloat32, 1},
              {"z", 8, PointField::kFloat32, 1},
              {"intensity", 12, PointField::kFloat32, 1}};
  c.point_step = 16;
  c.row_step = 16 * n;
  c.is_dense = true;
  c.data.resize(std::size_t(n) * 16);
  const std::uint32_t rings = 32;
  for (std::uint32_t i = 0; i < n; ++i) {
    const double azimuth = 2.0 * M_PI * double(i / rings) / double(n / rings + 1);
    const double elevation = (double(i % rings) - 15.5) * 0.02;
    const double range = 5.0 + 3.0 * std::sin(3.0 * azimuth + 0.1 * index) + 0.01 * (i % 7);
    const float p[4] = {float(range * std::cos(elevation) * std::cos(azimuth)),
                        float(range * std::cos(elevation) * std::sin(azimuth)),
                        float(range * std::sin(elevation)), float((i * 37 + index) % 256)};
    std::memcpy(c.data.data() + std::size_t(i) * 16, p, 16);
  }
  return c;
}

Image image(std::uint32_t width, std::uint32_t height, bool mono16, int index, std::int64_t ns,
            const std::string& frame) {
  Image m;
  m.header.stamp = stamp(ns);
  m.header.frame_id = frame;
  m.width = width;
  m.height = height;
  m.encoding = mono16 ? "mono16" : "rgb8";
  m.step = width * (mono16 ? 2 : 3);
  m.data.resize(std::size_t(m.step) * height);
  for (std::uint32_t r = 0; r < height; ++r) {
    for (std::uint32_t c = 0; c < width; ++c) {
      if (mono16) {
        const std::uint16_t v = std::uint16_t(7000 + ((r + index) % 64) * 8 + (c % 32));
        std::memcpy(m.data.data() + std::size_t(r) * m.step + c * 2, &v, 2);
      } else {
        std::uint8_t* px = m.data.data() + std::size_t(r) * m.step + c * 3;
        px[0] = std::uint8_t(r + index);
        px[1] = std::uint8_t(c);
        px[2] = std::uint8_t((r * c) >> 6);
      }
    }
  }
  return m;
}

// Writes the bag; returns the number of messages.
std::size_t write_bag(const fs::path& path, double size_mb, std::uint32_t points,
                      mcap::Compression compression) {
  mcap::McapWriterOptions options("ros2");
  options.compression = compression;
  mcap::McapWriter writer;
  const mcap::Status status = writer.open(path.string(), options);
  if (!status.ok()) throw std::runtime_error(path.string() + ": " + status.message);
  // Abridged definitions: rgbdt_import reads the type names only.
  mcap::Schema cloud_schema("sensor_msgs/msg/PointCloud2", "ros2msg",
                            "std_msgs/Header header\nuint32 height\nuint32 width\n...");
  mcap::Schema image_schema("sensor_msgs/msg/Image", "ros2msg",
                            "std_msgs/Header header\nuint32 height\nuint32 width\n...");
  mcap::Schema info_schema("sensor_msgs/msg/CameraInfo", "ros2msg",
                           "std_msgs/Header header\nuint32 height\nuint32 width\n...");
  writer.addSchema(cloud_schema);
  writer.addSchema(image_schema);
  writer.addSchema(info_schema);
  mcap::Channel points_channel("/lidar/points", "cdr", cloud_schema.id);
  mcap::Channel thermal_channel("/thermal/image_raw", "cdr", image_schema.id);
  mcap::Channel rgb_channel("/rgb/image_raw", "cdr", image_schema.id);
  mcap::Channel thermal_info("/thermal/camera_info", "cdr", info_schema.id);
  mcap::Channel rgb_info("/rgb/camera_info", "cdr", info_schema.id);
  for (mcap::Channel* c : {&points_channel, &thermal_channel, &rgb_channel, &thermal_info, &rgb_info})
    writer.addChannel(*c);

  std::size_t messages = 0;
  std::uint64_t bytes = 0;
  const auto put = [&](const mcap::Channel& channel, std::int64_t ns,
                       const std::vector<std::uint8_t>& data) {
    mcap::Message m;
    m.channelId = channel.id;
    m.sequence = std::uint32_t(messages);
    m.logTime = mcap::Timestamp(ns);
    m.publishTime = m.logTime;
    m.data = reinterpret_cast<const std::byte*>(data.data());
    m.dataSize = data.size();
    const mcap::Status written = writer.write(m);
    if (!written.ok()) throw std::runtime_error(path.string() + ": " + written.message);
    ++messages;
    bytes += data.size();
  };
  const auto camera_info = [&](std::uint32_t w, std::uint32_t h, const std::string& frame) {
    rgbdt::bag::CameraInfo info;
    info.header.stamp = stamp(kT0);
    info.header.frame_id = frame;
    info.width = w;
    info.height = h;
    info.distortion_model = "plumb_bob";
    info.d = {-0.1, 0.05, 0, 0, 0};
    info.k = {500, 0, w / 2.0, 0, 500, h / 2.0, 0, 0, 1};
    info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    info.p = {500, 0, w / 2.0, 0, 0, 500, h / 2.0, 0, 0, 0, 1, 0};
    return rgbdt::bag::test::encode(info);
  };
  put(thermal_info, kT0, camera_info(640, 512, "thermal"));
  put(rgb_info, kT0, camera_info(640, 480, "rgb"));
  const double target = size_mb * 1e6;
  for (int k = 0; double(bytes) < target; ++k) {
    const std::int64_t ns = kT0 + std::int64_t(k) * 100000000 + 1000000;
    put(points_channel, ns, rgbdt::bag::test::encode(cloud(points, k, ns)));
    put(thermal_channel, ns + 2000000,
        rgbdt::bag::test::encode(image(640, 512, true, k, ns + 2000000, "thermal")));
    if (k % 2 == 0)
      put(rgb_channel, ns + 3000000,
          rgbdt::bag::test::encode(image(640, 480, false, k, ns + 3000000, "rgb")));
    if (k % 50 == 0) std::fprintf(stderr, "\rwriting %s: %.0f MB", path.c_str(), double(bytes) / 1e6);
  }
  writer.close();
  std::fprintf(stderr, "\n");
  return messages;
}

struct Timed {
  double wall_s = 0, cpu_s = 0;
  long peak_rss_kb = 0;
  int exit_code = -1;
};

// Runs argv[0] with argv (output to `log`), timing it and taking its resource use.
Timed run(const std::vector<std::string>& args, const fs::path& log) {
  std::vector<std::string> all = args;
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  Timed t;
  if (rc != 0) {
    std::cerr << "cannot run " << args[0] << "\n";
    return t;
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  t.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  t.cpu_s = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
            1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
  t.peak_rss_kb = usage.ru_maxrss;
  t.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rgbdt_import's MB/s beside cp of the same MCAP bag, and its peak memory"};
  double size_mb = 500;
  std::uint32_t points = 100000;
  std::string dir = (fs::temp_directory_path() / "rgbdt_import_bench").string();
  std::string import_program;
  std::string compression = "none";
  bool keep = false;
  app.add_option("--size-mb", size_mb, "the bag's size [MB]; 2048 for the issue's 2 GB bag")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--points", points, "points per cloud (16 bytes each), clouds at 10 Hz")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--dir", dir, "scratch folder for the bag, its copy and the session")
      ->capture_default_str();
  app.add_option("--import", import_program, "the rgbdt_import to time (default: beside this program)");
  app.add_option("--compression", compression, "MCAP chunk compression")
      ->check(CLI::IsMember({"none", "lz4", "zstd"}))
      ->capture_default_str();
  app.add_flag("--keep", keep, "keep the scratch folder");
  CLI11_PARSE(app, argc, argv);
  if (import_program.empty())
    import_program = (fs::canonical("/proc/self/exe").parent_path() / "rgbdt_import").string();

  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path bag = fs::path(dir) / "bench.mcap";
  const fs::path copy = fs::path(dir) / "copy.mcap";
  const fs::path session = fs::path(dir) / "session";
  const auto write_start = std::chrono::steady_clock::now();
  const std::size_t messages =
      write_bag(bag, size_mb, points,
                compression == "lz4"    ? mcap::Compression::Lz4
                : compression == "zstd" ? mcap::Compression::Zstd
                                        : mcap::Compression::None);
  const double write_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - write_start).count();
  const double mb = double(fs::file_size(bag)) / 1e6;
  std::printf("bag: %s, %.0f MB, %zu messages (%u-point clouds at 10 Hz, mono16 640x512 at 10 Hz, "
              "rgb8 640x480 at 5 Hz; %s chunks), written in %.1f s\n",
              bag.c_str(), mb, messages, points, compression.c_str(), write_s);
  std::fflush(stdout);

  // cp first, so that both read the bag from the same cache state (just written).
  const Timed cp = run({"cp", bag.string(), copy.string()}, fs::path(dir) / "cp.log");
  fs::remove(copy);
  const Timed import = run({import_program, bag.string(), "--out", session.string(), "--kind",
                            "mapping", "--lidar", "/lidar/points", "--camera",
                            "thermal=/thermal/image_raw", "--camera", "rgb=/rgb/image_raw"},
                           fs::path(dir) / "import.log");
  // The clouds alone: the difference is what the camera frames cost.
  const fs::path lidar_session = fs::path(dir) / "session_lidar";
  const Timed lidar_only = run({import_program, bag.string(), "--out", lidar_session.string(),
                                "--kind", "mapping", "--lidar", "/lidar/points"},
                               fs::path(dir) / "import_lidar.log");
  if (cp.exit_code != 0 || import.exit_code != 0 || lidar_only.exit_code != 0) {
    std::fprintf(stderr,
                 "import_bench: cp exited %d, rgbdt_import exited %d and %d (logs in %s)\n",
                 cp.exit_code, import.exit_code, lidar_only.exit_code, dir.c_str());
    return 1;
  }
  std::size_t session_bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(session))
    if (e.is_regular_file()) session_bytes += e.file_size();

  std::printf("\n| program | wall [s] | CPU [s] | MB/s (wall) | MB/s (CPU) | peak RSS [MB] |\n");
  std::printf("|---|---|---|---|---|---|\n");
  const auto row = [&](const char* name, const Timed& t) {
    std::printf("| %s | %.2f | %.2f | %.0f | %.0f | %.0f |\n", name, t.wall_s, t.cpu_s,
                mb / t.wall_s, mb / std::max(t.cpu_s, 1e-6), double(t.peak_rss_kb) / 1024.0);
  };
  row("cp", cp);
  row("rgbdt_import --kind mapping (clouds + 2 cameras)", import);
  row("rgbdt_import --kind mapping (clouds only)", lidar_only);
  std::printf("\nimport / cp: %.1fx the wall time; import peak RSS %.0f MB for a %.0f MB bag; "
              "session written: %.0f MB\n",
              import.wall_s / cp.wall_s, double(import.peak_rss_kb) / 1024.0, mb,
              double(session_bytes) / 1e6);
  if (!keep) fs::remove_all(dir);
  return 0;
}
