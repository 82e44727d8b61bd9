#include "import.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>

#include "convert.hpp"
#include "rgbdt/bag/messages.hpp"
#include "rgbdt/bag/point_cloud.hpp"
#include "rgbdt/bag/reader.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/interrupt.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "still.hpp"

namespace rgbdt::import {
namespace {

namespace fs = std::filesystem;

bool type_is(const std::string& type, const char* name) {
  // ROS 1 "sensor_msgs/Image", ROS 2 "sensor_msgs/msg/Image".
  return type == std::string("sensor_msgs/") + name ||
         type == std::string("sensor_msgs/msg/") + name;
}

std::string topic_list(const bag::BagReader& reader) {
  std::string out;
  for (const auto& t : reader.topics()) {
    out += (out.empty() ? "" : ", ") + t.name + " (" + t.type + ")";
  }
  return out.empty() ? "no topics" : out;
}

// The topic `name` of the bag, checked to hold one of `types` in a serialization the decoders
// read; `role` says what it is for, in errors.
bag::TopicInfo require_topic(const bag::BagReader& reader, const fs::path& bag_path,
                             const std::string& name, std::initializer_list<const char*> types,
                             const std::string& role) {
  const bag::TopicInfo* topic = reader.find_topic(name);
  if (!topic) {
    throw core::Error(bag_path.string(), role + " topic " + name + " is not in the bag (it holds " +
                                             topic_list(reader) + ")");
  }
  bool known = false;
  std::string expected;
  for (const char* t : types) {
    known = known || type_is(topic->type, t);
    expected += (expected.empty() ? "sensor_msgs/" : " or sensor_msgs/") + std::string(t);
  }
  if (!known) {
    throw core::Error(bag_path.string(), role + " topic " + name + " has type " + topic->type +
                                             ", expected " + expected);
  }
  try {
    bag::serialization_of(*topic);
  } catch (const core::Error& e) {
    throw core::Error(bag_path.string(), e.what());
  }
  return *topic;
}

// "/cam/image_raw" and "/cam/image_raw/compressed" -> "/cam/camera_info".
std::string sibling_camera_info(std::string topic) {
  const std::string compressed = "/compressed";
  if (topic.size() > compressed.size() &&
      topic.compare(topic.size() - compressed.size(), compressed.size(), compressed) == 0) {
    topic.erase(topic.size() - compressed.size());
  }
  const std::size_t slash = topic.rfind('/');
  return (slash == std::string::npos ? std::string("/") : topic.substr(0, slash + 1)) +
         "camera_info";
}

std::uint64_t bag_bytes(const fs::path& path) {
  std::error_code ec;
  if (fs::is_regular_file(path, ec)) return fs::file_size(path, ec);
  std::uint64_t total = 0;
  for (const auto& entry : fs::directory_iterator(path, ec)) {
    if (entry.is_regular_file(ec)) total += entry.file_size(ec);
  }
  return total;
}

std::string index_name(std::size_t i, int digits) {
  std::ostringstream os;
  os << std::setw(digits) << std::setfill('0') << i;
  return os.str();
}

// Progress on stderr, at most once a second.
class Progress {
 public:
  Progress(std::string label, std::uint64_t total_bytes)
      : label_(std::move(label)),
        total_mb_(double(total_bytes) / 1e6),
        t0_(Clock::now()),
        last_(t0_) {}

  void add(std::size_t bytes) {
    ++messages_;
    bytes_ += bytes;
    const auto now = Clock::now();
    if (now - last_ >= std::chrono::seconds(1)) {
      last_ = now;
      print(now);
    }
  }
  void finish() { print(Clock::now()); }
  std::size_t messages() const { return messages_; }

 private:
  using Clock = std::chrono::steady_clock;
  void print(Clock::time_point now) const {
    std::fprintf(stderr, "%s: %zu messages, %.1f MB read (bag %.1f MB), %.1f s\n", label_.c_str(),
                 messages_, double(bytes_) / 1e6, total_mb_,
                 std::chrono::duration<double>(now - t0_).count());
  }
  std::string label_;
  double total_mb_;
  Clock::time_point t0_, last_;
  std::size_t messages_ = 0;
  std::uint64_t bytes_ = 0;
};

void check_interrupt() {
  if (core::interrupted()) throw Interrupted{};
}

// The session folder being written: a hidden sibling of the final folder, renamed into place
// by commit() and removed when destroyed before that.
class StagingDir {
 public:
  explicit StagingDir(const fs::path& out) : out_(fs::absolute(out).lexically_normal()) {
    if (out_.filename().empty()) out_ = out_.parent_path();
    std::error_code ec;
    if (fs::exists(out_, ec) && !(fs::is_directory(out_, ec) && fs::is_empty(out_, ec))) {
      throw core::Error(out_.string(), "exists and is not an empty folder (choose a new --out)");
    }
    fs::create_directories(out_.parent_path(), ec);
    dir_ = out_.parent_path() /
           ("." + out_.filename().string() + ".importing-" + std::to_string(::getpid()));
    fs::remove_all(dir_, ec);
    if (!fs::create_directories(dir_, ec) || ec) {
      throw core::Error(dir_.string(), "cannot create the temporary session folder" +
                                           (ec ? " (" + ec.message() + ")" : std::string()));
    }
  }
  ~StagingDir() {
    if (!committed_) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
    }
  }
  StagingDir(const StagingDir&) = delete;
  StagingDir& operator=(const StagingDir&) = delete;

  const fs::path& dir() const { return dir_; }
  fs::path operator/(const std::string& relative) const { return dir_ / relative; }

  void commit() {
    std::error_code ec;
    if (fs::is_directory(out_, ec)) fs::remove(out_, ec);  // empty (checked at the start)
    fs::rename(dir_, out_, ec);
    if (ec)
      throw core::Error(out_.string(),
                        "cannot rename the finished session into place (" + ec.message() + ")");
    committed_ = true;
  }

 private:
  fs::path out_;
  fs::path dir_;
  bool committed_ = false;
};

void write_png(const fs::path& path, const cv::Mat& image) {
  fs::create_directories(path.parent_path());
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), image);
  } catch (const cv::Exception& e) {
    throw core::Error(path.string(), std::string("cannot write the PNG: ") + e.what());
  }
  if (!ok) throw core::Error(path.string(), "cannot write the PNG");
}

std::int64_t stamp_or_log_time(const bag::Header& header, std::int64_t log_time_ns) {
  const std::int64_t stamp = header.stamp.to_ns();
  return stamp != 0 ? stamp : log_time_ns;
}

// One camera of the import, its topics resolved.
struct Camera {
  CameraSource source;
  bag::TopicInfo image;
  bool compressed = false;
  std::optional<bag::TopicInfo> info;  // none when intrinsics come from a file
  bool have_intrinsics = false;
  std::vector<core::TimedFile> frames;
};

// Everything resolved before the first message: topics (copied: each pass opens its own
// reader, so messages are matched to them by name), the time window.
struct Plan {
  bag::TopicInfo lidar;
  std::optional<bag::TopicInfo> imu;
  std::vector<Camera> cameras;
  bag::ReadOptions window;  // start and end only
};

Plan make_plan(const ImportOptions& options, const bag::BagReader& reader) {
  Plan plan;
  plan.lidar = require_topic(reader, options.bag, options.lidar_topic, {"PointCloud2"}, "LIDAR");
  if (!options.imu_topic.empty()) {
    plan.imu = require_topic(reader, options.bag, options.imu_topic, {"Imu"}, "IMU");
  }
  std::set<std::string> names;
  for (const CameraSource& source : options.cameras) {
    if (!core::is_valid_camera_name(source.name)) {
      throw std::invalid_argument("camera name '" + source.name +
                                  "' is not usable as a file name (1 to 64 of A-Z a-z 0-9 _ -)");
    }
    if (!names.insert(source.name).second) {
      throw std::invalid_argument("camera " + source.name + " is given twice");
    }
    Camera camera;
    camera.source = source;
    camera.image = require_topic(reader, options.bag, source.topic, {"Image", "CompressedImage"},
                                 "camera " + source.name + " image");
    camera.compressed = type_is(camera.image.type, "CompressedImage");
    if (source.intrinsics.empty()) {
      if (!source.info_topic.empty()) {
        camera.info = require_topic(reader, options.bag, source.info_topic, {"CameraInfo"},
                                    "camera " + source.name + " camera_info");
      } else {
        const std::string sibling = sibling_camera_info(source.topic);
        if (!reader.find_topic(sibling)) {
          throw core::Error(options.bag.string(),
                            "camera " + source.name + ": no CameraInfo topic " + sibling +
                                " beside " + source.topic + " (pass --camera-info " + source.name +
                                "=TOPIC or --intrinsics " + source.name + "=FILE.yaml)");
        }
        camera.info = require_topic(reader, options.bag, sibling, {"CameraInfo"},
                                    "camera " + source.name + " camera_info");
      }
    }
    plan.cameras.push_back(std::move(camera));
  }
  return plan;
}

// The bag's first log time, to which --start and --end count.
std::int64_t first_log_time(const fs::path& bag_path) {
  const auto reader = bag::open_bag(bag_path);
  const auto first = reader->next();
  if (!first) throw core::Error(bag_path.string(), "the bag holds no messages");
  return first->log_time_ns;
}

bag::ReadOptions time_window(const ImportOptions& options) {
  bag::ReadOptions window;
  if (!options.start_s && !options.end_s) return window;
  const std::int64_t t0 = first_log_time(options.bag);
  if (options.start_s) window.start_ns = t0 + std::llround(*options.start_s * 1e9);
  if (options.end_s) window.end_ns = t0 + std::llround(*options.end_s * 1e9);
  return window;
}

std::unique_ptr<bag::BagReader> open_topics(const ImportOptions& options, const Plan& plan,
                                            std::vector<std::string> topics) {
  bag::ReadOptions read = plan.window;
  std::sort(topics.begin(), topics.end());
  topics.erase(std::unique(topics.begin(), topics.end()), topics.end());
  read.topics = topics;
  return bag::open_bag(options.bag, read);
}

cv::Mat decode_frame(const Camera& camera, const bag::BagMessage& message,
                     const bag::MessageContext& context, std::int64_t* time_ns) {
  if (camera.compressed) {
    const bag::CompressedImage image =
        bag::decode_compressed_image(message.data, message.size, context);
    *time_ns = stamp_or_log_time(image.header, message.log_time_ns);
    return compressed_to_mat(image, context);
  }
  const bag::Image image = bag::decode_image(message.data, message.size, context);
  *time_ns = stamp_or_log_time(image.header, message.log_time_ns);
  return image_to_mat(image, context);
}

PcdCloud decode_cloud(const bag::BagMessage& message, const bag::MessageContext& context) {
  const bag::PointCloud2 cloud = bag::decode_point_cloud2(message.data, message.size, context);
  const bag::CloudPoints points = bag::extract_points(cloud, context);
  return to_pcd_cloud(points, stamp_or_log_time(cloud.header, message.log_time_ns));
}

// Writes <name>.yaml from the first CameraInfo of the camera, or copies --intrinsics.
void write_intrinsics(Camera& camera, const StagingDir& dir, const bag::BagMessage* message) {
  const fs::path path = dir / (camera.source.name + ".yaml");
  if (message == nullptr) {
    const core::CameraIntrinsics in = core::read_camera_info(camera.source.intrinsics);
    core::write_camera_info(path.string(), in);
  } else {
    const bag::MessageContext context = bag::context_of(*message);
    const bag::CameraInfo info = bag::decode_camera_info(message->data, message->size, context);
    core::write_camera_info(path.string(), to_intrinsics(info, camera.source.name, context));
  }
  camera.have_intrinsics = true;
}

void require_intrinsics(const std::vector<Camera>& cameras, const ImportOptions& options) {
  for (const Camera& camera : cameras) {
    if (!camera.have_intrinsics) {
      throw core::Error(options.bag.string(),
                        "camera " + camera.source.name + ": no CameraInfo message on " +
                            camera.info->name + " in the imported time range");
    }
  }
}

std::string format_time(std::int64_t ns) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", double(ns) * 1e-9);
  return buf;
}

// ---------------------------------------------------------------------------------------
// Mapping: every message becomes a file.

ImportResult import_mapping(const ImportOptions& options, Plan& plan, StagingDir& dir) {
  ImportResult result;
  std::vector<std::string> topics = {plan.lidar.name};
  std::map<std::string, std::vector<Camera*>> by_image, by_info;
  for (Camera& camera : plan.cameras) {
    topics.push_back(camera.image.name);
    by_image[camera.image.name].push_back(&camera);
    if (camera.info) {
      topics.push_back(camera.info->name);
      by_info[camera.info->name].push_back(&camera);
    } else {
      write_intrinsics(camera, dir, nullptr);
    }
    fs::create_directories(dir / camera.source.name);
  }
  std::ofstream imu;
  if (plan.imu) {
    topics.push_back(plan.imu->name);
    imu.open(dir / "imu.csv");
    imu << "time_s,wx,wy,wz,ax,ay,az\n" << std::setprecision(17);
  }
  fs::create_directories(dir / "clouds");
  std::vector<core::TimedFile> clouds;

  const auto reader = open_topics(options, plan, topics);
  Progress progress("rgbdt_import", bag_bytes(options.bag));
  while (const auto message = reader->next()) {
    check_interrupt();
    progress.add(message->size);
    const bag::MessageContext context = bag::context_of(*message);
    if (message->topic->name == plan.lidar.name) {
      const PcdCloud cloud = decode_cloud(*message, context);
      const fs::path file = dir / ("clouds/" + index_name(clouds.size(), 6) + ".pcd");
      core::write_file_atomic(file.string(), format_pcd(cloud));
      clouds.push_back({double(cloud.first_time_ns) * 1e-9, file.string()});
    } else if (plan.imu && message->topic->name == plan.imu->name) {
      const bag::Imu sample = bag::decode_imu(message->data, message->size, context);
      imu << double(stamp_or_log_time(sample.header, message->log_time_ns)) * 1e-9 << ','
          << sample.angular_velocity.x << ',' << sample.angular_velocity.y << ','
          << sample.angular_velocity.z << ',' << sample.linear_acceleration.x << ','
          << sample.linear_acceleration.y << ',' << sample.linear_acceleration.z << '\n';
      ++result.imu_samples;
    }
    // A topic may serve two roles (one camera's info topic for another); both are handled.
    if (const auto it = by_image.find(message->topic->name); it != by_image.end()) {
      for (Camera* camera : it->second) {
        std::int64_t t_ns = 0;
        const cv::Mat image = decode_frame(*camera, *message, context, &t_ns);
        const fs::path file =
            dir / (camera->source.name + "/" + index_name(camera->frames.size(), 6) + ".png");
        write_png(file, image);
        camera->frames.push_back({double(t_ns) * 1e-9, file.string()});
      }
    }
    if (const auto it = by_info.find(message->topic->name); it != by_info.end()) {
      for (Camera* camera : it->second) {
        if (!camera->have_intrinsics) write_intrinsics(*camera, dir, &*message);
      }
    }
  }
  progress.finish();
  result.messages = progress.messages();
  if (clouds.empty()) {
    throw core::Error(options.bag.string(), "no PointCloud2 message on " + plan.lidar.name +
                                                " in the imported time range");
  }
  require_intrinsics(plan.cameras, options);
  if (plan.imu) {
    imu.flush();
    if (!imu) throw core::Error((dir / "imu.csv").string(), "cannot write the IMU samples");
  }

  // Indexes are sorted by time (read_time_index requires it); header stamps may come out of
  // log-time order by a little.
  const auto by_time = [](const core::TimedFile& a, const core::TimedFile& b) {
    return a.time_s < b.time_s;
  };
  std::stable_sort(clouds.begin(), clouds.end(), by_time);
  core::write_time_index((dir / "clouds/index.csv").string(), clouds);
  core::MappingSession session;
  session.lidar.clouds = (dir / "clouds/index.csv").string();
  for (Camera& camera : plan.cameras) {
    std::stable_sort(camera.frames.begin(), camera.frames.end(), by_time);
    const fs::path index = dir / (camera.source.name + "/index.csv");
    core::write_time_index(index.string(), camera.frames);
    session.cameras[camera.source.name] = {(dir / (camera.source.name + ".yaml")).string(),
                                           index.string(), camera.source.radiometry};
    result.frames.emplace_back(camera.source.name, camera.frames.size());
  }
  if (plan.imu) session.imu = core::ImuStream{(dir / "imu.csv").string()};
  core::write_mapping_session((dir / "session.yaml").string(), session);
  result.clouds = clouds.size();
  return result;
}

// ---------------------------------------------------------------------------------------
// Calibration: still intervals become views.

struct Interval {
  std::int64_t start_ns = 0, end_ns = 0;  // first and last still frame
  std::size_t frames = 0;
  std::string dropped;  // why it is not a view; empty when kept
  PcdCloud cloud;
  std::size_t clouds = 0;
  std::int64_t middle_ns() const { return start_ns + (end_ns - start_ns) / 2; }
};

// Pass 1: the still camera's frame times and differences, split into runs.
std::vector<Interval> find_still_intervals(const ImportOptions& options, const Plan& plan,
                                           const Camera& camera) {
  const auto reader = open_topics(options, plan, {camera.image.name});
  Progress progress("rgbdt_import (pass 1 of 2: still intervals)", bag_bytes(options.bag));
  FrameDifference difference;
  std::vector<double> differences;
  std::vector<std::int64_t> times;
  while (const auto message = reader->next()) {
    check_interrupt();
    progress.add(message->size);
    std::int64_t t_ns = 0;
    const cv::Mat image = decode_frame(camera, *message, bag::context_of(*message), &t_ns);
    differences.push_back(difference.add(image).value_or(0.0));
    times.push_back(t_ns);
  }
  progress.finish();
  if (times.empty()) {
    throw core::Error(options.bag.string(),
                      "no image on " + camera.image.name + " in the imported time range");
  }
  std::vector<Interval> intervals;
  for (const FrameRun& run : split_runs(differences, options.still_threshold)) {
    Interval interval;
    interval.start_ns = times[run.first];
    interval.end_ns = times[run.last];
    interval.frames = run.frames();
    if (run.frames() < static_cast<std::size_t>(options.min_still_frames)) {
      interval.dropped = std::to_string(run.frames()) +
                         " still frame(s), fewer than --min-still-frames " +
                         std::to_string(options.min_still_frames);
    }
    intervals.push_back(std::move(interval));
  }
  return intervals;
}

// The image of one camera nearest the middle of one interval, so far.
struct Candidate {
  std::int64_t distance_ns = std::numeric_limits<std::int64_t>::max();
  cv::Mat image;
};

// The board of --target, checked as session.yaml's target entry.
core::TargetSpec board_target(const ImportOptions& options) {
  return core::parse_calibration_session("target: " + options.target_yaml +
                                             "\ncameras: {}\nviews: [{cloud: x.pcd, images: {}}]\n",
                                         "--target")
      .target;
}

// The intervals that may become views: the still camera's (pass 1), or without a camera the
// imported time range as one still interval.
std::vector<Interval> candidate_intervals(const ImportOptions& options, const Plan& plan) {
  if (plan.cameras.empty()) {
    std::vector<Interval> intervals;
    Interval all;
    all.start_ns = plan.window.start_ns;
    all.end_ns = plan.window.end_ns;
    intervals.push_back(std::move(all));
    return intervals;
  }
  auto still = std::find_if(plan.cameras.begin(), plan.cameras.end(),
                            [&](const Camera& c) { return c.source.name == options.still_camera; });
  if (options.still_camera.empty()) still = plan.cameras.begin();
  if (still == plan.cameras.end()) {
    throw std::invalid_argument("--still-camera " + options.still_camera +
                                " is not one of the --camera names");
  }
  return find_still_intervals(options, plan, *still);
}

// The topics pass 2 reads and the cameras each image or CameraInfo topic serves.
struct Routes {
  std::vector<std::string> topics;
  std::map<std::string, std::vector<std::size_t>> by_image, by_info;  // -> camera indices
};

// The routes of pass 2; the intrinsics of cameras with --intrinsics are written here.
Routes route_topics(Plan& plan, const StagingDir& dir) {
  Routes routes;
  routes.topics = {plan.lidar.name};
  for (std::size_t c = 0; c < plan.cameras.size(); ++c) {
    Camera& camera = plan.cameras[c];
    routes.topics.push_back(camera.image.name);
    routes.by_image[camera.image.name].push_back(c);
    if (camera.info) {
      routes.topics.push_back(camera.info->name);
      routes.by_info[camera.info->name].push_back(c);
    } else {
      write_intrinsics(camera, dir, nullptr);
    }
  }
  return routes;
}

// The interval index a time falls in, or -1 (intervals are sorted and disjoint).
long interval_of(const std::vector<Interval>& intervals, std::int64_t t) {
  const auto it =
      std::upper_bound(intervals.begin(), intervals.end(), t,
                       [](std::int64_t v, const Interval& i) { return v < i.start_ns; });
  if (it == intervals.begin()) return -1;
  const long i = static_cast<long>(it - intervals.begin()) - 1;
  return t <= intervals[i].end_ns ? i : -1;
}

// What pass 2 gathers: per interval its clouds accumulated and, per camera, the frame
// nearest its middle.
struct ViewData {
  std::vector<Interval> intervals;
  std::vector<std::vector<Candidate>> candidates;  // [interval][camera]
};

// A LIDAR cloud joins the kept interval it starts in.
void add_cloud(const ImportOptions& options, const bag::BagMessage& message,
               const bag::MessageContext& context, ViewData& data, ImportResult& result) {
  PcdCloud cloud = decode_cloud(message, context);
  const long i = interval_of(data.intervals, cloud.first_time_ns);
  if (i < 0 || !data.intervals[i].dropped.empty()) return;
  Interval& interval = data.intervals[i];
  if (interval.cloud.size() + cloud.size() > options.max_view_points) {
    throw core::Error(options.bag.string(),
                      "the still interval from " + format_time(interval.start_ns) +
                          " s holds more than " + std::to_string(options.max_view_points) +
                          " points (narrow it with --start/--end, or raise --max-view-points)");
  }
  append_cloud(interval.cloud, cloud);
  ++interval.clouds;
  ++result.clouds;
}

// Camera c's frame becomes its candidate for the kept interval it falls in when nearer the
// interval's middle than the one so far.
void consider_frame(const Camera& camera, std::size_t c, const bag::BagMessage& message,
                    const bag::MessageContext& context, ViewData& data) {
  std::int64_t t_ns = 0;
  // Only frames inside a kept interval are decoded fully; the header stamp comes first.
  const bag::Header header =
      camera.compressed ? bag::decode_compressed_image(message.data, message.size, context).header
                        : bag::decode_image(message.data, message.size, context).header;
  t_ns = stamp_or_log_time(header, message.log_time_ns);
  const long i = interval_of(data.intervals, t_ns);
  if (i < 0 || !data.intervals[i].dropped.empty()) return;
  Candidate& best = data.candidates[i][c];
  const std::int64_t distance = std::llabs(t_ns - data.intervals[i].middle_ns());
  if (distance < best.distance_ns) {
    best.distance_ns = distance;
    best.image = decode_frame(camera, message, context, &t_ns);
  }
}

// Pass 2: reads the LIDAR, image and CameraInfo messages into `data` and the cameras'
// intrinsics files.
void collect_views(const ImportOptions& options, Plan& plan, const StagingDir& dir,
                   const Routes& routes, ViewData& data, ImportResult& result) {
  const auto reader = open_topics(options, plan, routes.topics);
  Progress progress("rgbdt_import (pass 2 of 2: views)", bag_bytes(options.bag));
  while (const auto message = reader->next()) {
    check_interrupt();
    progress.add(message->size);
    const bag::MessageContext context = bag::context_of(*message);
    if (message->topic->name == plan.lidar.name)
      add_cloud(options, *message, context, data, result);
    if (const auto it = routes.by_image.find(message->topic->name); it != routes.by_image.end()) {
      for (std::size_t c : it->second) consider_frame(plan.cameras[c], c, *message, context, data);
    }
    if (const auto it = routes.by_info.find(message->topic->name); it != routes.by_info.end()) {
      for (std::size_t c : it->second) {
        if (!plan.cameras[c].have_intrinsics) write_intrinsics(plan.cameras[c], dir, &*message);
      }
    }
  }
  progress.finish();
  result.messages = progress.messages();
}

// Why a kept interval still cannot be a view after pass 2; empty when it can.
std::string missing_data(const Interval& interval, const std::vector<Candidate>& frames,
                         const Plan& plan) {
  if (interval.cloud.size() == 0) {
    return interval.clouds == 0 ? "no LIDAR cloud inside it" : "its clouds have no finite point";
  }
  for (std::size_t c = 0; c < plan.cameras.size(); ++c) {
    if (frames[c].image.empty()) return "no " + plan.cameras[c].source.name + " image inside it";
  }
  return "";
}

// An interval as the lines of the report name it.
std::string interval_span(const Interval& interval, const Plan& plan) {
  return plan.cameras.empty()
             ? std::string("the whole imported range")
             : format_time(interval.start_ns) + " - " + format_time(interval.end_ns) + " s (" +
                   std::to_string(interval.frames) + " still frames)";
}

// View `name` from an interval: its accumulated cloud and each camera's frame.
core::CalibrationView write_view(const std::string& name, const Interval& interval,
                                 const std::vector<Candidate>& frames, const Plan& plan,
                                 const StagingDir& dir) {
  core::CalibrationView view;
  view.cloud = (dir / ("clouds/" + name + ".pcd")).string();
  core::write_file_atomic(view.cloud, format_pcd(interval.cloud));
  for (std::size_t c = 0; c < plan.cameras.size(); ++c) {
    const std::string& cam = plan.cameras[c].source.name;
    const fs::path png = dir / (cam + "/" + name + ".png");
    write_png(png, frames[c].image);
    view.images[cam] = png.string();
  }
  return view;
}

// Views: the kept intervals with a cloud and an image of every camera, numbered in order;
// one line per interval to `report`.
void write_views(ViewData& data, const Plan& plan, const StagingDir& dir, std::FILE* report,
                 core::CalibrationSession& session) {
  for (std::size_t i = 0; i < data.intervals.size(); ++i) {
    Interval& interval = data.intervals[i];
    if (interval.dropped.empty())
      interval.dropped = missing_data(interval, data.candidates[i], plan);
    std::string span = interval_span(interval, plan);
    if (!interval.dropped.empty()) {
      std::fprintf(report, "interval %zu: %s: dropped, %s\n", i, span.c_str(),
                   interval.dropped.c_str());
      continue;
    }
    const std::string name = index_name(session.views.size(), 3);
    core::CalibrationView view = write_view(name, interval, data.candidates[i], plan, dir);
    std::fprintf(report, "interval %zu: %s: kept as view %s (%zu clouds, %zu points)\n", i,
                 span.c_str(), name.c_str(), interval.clouds, interval.cloud.size());
    session.views.push_back(std::move(view));
    interval.cloud = PcdCloud{};
    data.candidates[i].clear();
  }
}

// Pass 2: accumulates each kept interval's clouds and keeps each camera's frame nearest its
// middle; views are written as their intervals close.
ImportResult import_calibration(const ImportOptions& options, Plan& plan, StagingDir& dir,
                                std::FILE* report) {
  ImportResult result;
  core::CalibrationSession session;
  session.target = board_target(options);
  ViewData data;
  data.intervals = candidate_intervals(options, plan);
  const Routes routes = route_topics(plan, dir);
  fs::create_directories(dir / "clouds");
  data.candidates.assign(data.intervals.size(), std::vector<Candidate>(plan.cameras.size()));
  collect_views(options, plan, dir, routes, data, result);
  require_intrinsics(plan.cameras, options);
  write_views(data, plan, dir, report, session);
  if (session.views.empty()) {
    throw core::Error(options.bag.string(),
                      "no still interval became a view (see the lines above; "
                      "--still-threshold and --min-still-frames set what counts as still)");
  }
  for (const Camera& camera : plan.cameras) {
    session.cameras[camera.source.name].intrinsics =
        (dir / (camera.source.name + ".yaml")).string();
    session.cameras[camera.source.name].radiometry = camera.source.radiometry;
  }
  core::write_calibration_session((dir / "session.yaml").string(), session);
  result.views = session.views.size();
  return result;
}

// A frame_id as ROS names frames: letters, digits, '_', '/', '.' and '-'.
bool is_ros_frame_id(const std::string& frame) {
  if (frame.empty()) return false;
  for (const char c : frame)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '/' && c != '.' && c != '-')
      return false;
  return true;
}

// frames.yaml: the header.frame_id of the first message of the LIDAR's and of each camera's
// image topic (in the time window), for rgbdt_calibrate's ROS outputs. An empty frame_id is
// left out, and one with other characters than a ROS frame's is left out saying so; without
// any, no file. Only topics known to hold a message in the window are read, so the reader
// stops after their first messages instead of running through the bag again: the LIDAR's
// (the import needs one), every camera's in a calibration (each view has a frame of each),
// and in a mapping the cameras that wrote frames.
void write_frames(const ImportOptions& options, const Plan& plan, const StagingDir& dir,
                  std::FILE* report) {
  std::map<std::string, std::string> sensor_of{{plan.lidar.name, "lidar"}};
  for (const Camera& camera : plan.cameras) {
    if (options.kind == SessionKind::kMapping && camera.frames.empty()) continue;
    sensor_of[camera.image.name] = camera.source.name;
  }
  std::vector<std::string> topics;
  for (const auto& [topic, sensor] : sensor_of) topics.push_back(topic);
  std::map<std::string, std::string> frame_of;  // sensor -> frame_id
  const auto reader = open_topics(options, plan, topics);
  std::size_t seen = 0;
  while (seen < sensor_of.size()) {
    const auto message = reader->next();
    if (!message) break;
    const std::string& sensor = sensor_of.at(message->topic->name);
    if (frame_of.count(sensor)) continue;
    const bag::MessageContext context = bag::context_of(*message);
    bag::Header header;
    if (sensor == "lidar") {
      header = bag::decode_point_cloud2(message->data, message->size, context).header;
    } else {
      const auto camera = std::find_if(plan.cameras.begin(), plan.cameras.end(),
                                       [&](const Camera& c) { return c.source.name == sensor; });
      header = camera->compressed
                   ? bag::decode_compressed_image(message->data, message->size, context).header
                   : bag::decode_image(message->data, message->size, context).header;
    }
    frame_of[sensor] = header.frame_id;
    ++seen;
  }
  std::ostringstream yaml;
  yaml << "# Each sensor's ROS frame_id, from the header of its first message in the bag\n"
          "# (rgbdt_import). rgbdt_calibrate names the frames of its ROS outputs after it.\n";
  bool any = false;
  for (const auto& [sensor, frame] : frame_of) {
    if (frame.empty()) continue;
    if (!is_ros_frame_id(frame)) {
      if (report) std::fprintf(report, "frame_id of %s left out of frames.yaml: not a ROS frame name\n", sensor.c_str());
      continue;
    }
    yaml << sensor << ": " << frame << "\n";
    any = true;
  }
  if (any) core::write_file_atomic((dir / "frames.yaml").string(), yaml.str());
}

}  // namespace

ImportResult import_bag(const ImportOptions& options, std::FILE* report) {
  if (options.kind == SessionKind::kCalibration && options.target_yaml.empty()) {
    throw std::invalid_argument(
        "--kind calibration needs --target (the board, as in session.yaml)");
  }
  if (options.start_s && options.end_s && !(*options.start_s < *options.end_s)) {
    throw std::invalid_argument("--start must be before --end");
  }
  Plan plan;
  {
    const auto reader = bag::open_bag(options.bag);
    plan = make_plan(options, *reader);
  }
  plan.window = time_window(options);
  StagingDir dir(options.out);
  ImportResult result = options.kind == SessionKind::kMapping
                            ? import_mapping(options, plan, dir)
                            : import_calibration(options, plan, dir, report);
  write_frames(options, plan, dir, report);
  dir.commit();
  return result;
}

}  // namespace rgbdt::import
