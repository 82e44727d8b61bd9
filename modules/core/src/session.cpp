#include "rgbdt/core/session.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace fs = std::filesystem;

namespace rgbdt::core {
namespace {

struct Where {
  std::string yaml_path;
  fs::path dir;
};

// Limits of a plausible target and session.
constexpr double kMaxTargetRadiusM = 5.0;
constexpr double kMaxBoardSideM = 20.0;
constexpr std::size_t kMaxHoles = 64;
constexpr std::size_t kMaxViews = 100000;
constexpr double kMaxSeedRangeM = 1000.0;

Where place(const std::string& yaml_path) {
  const fs::path p = fs::absolute(fs::path(yaml_path)).lexically_normal();
  return {p.string(), p.parent_path()};
}

Where locate(const std::string& path) {
  fs::path p(path);
  if (fs::is_directory(p)) p /= "session.yaml";
  if (!fs::exists(p)) {
    throw Error(p.string(), "no session.yaml here (expected a session folder or its session.yaml)");
  }
  p = fs::absolute(p).lexically_normal();
  return {p.string(), p.parent_path()};
}

std::string resolve(const Where& w, const std::string& rel) {
  const fs::path p(rel);
  return (p.is_absolute() ? p : w.dir / p).lexically_normal().string();
}

std::string relative_to(const fs::path& dir, const std::string& path) {
  if (path.empty()) return path;
  fs::path p(path);
  if (!p.is_absolute()) return path;
  const fs::path rel = p.lexically_relative(dir);
  if (rel.empty() || *rel.begin() == "..") return path;
  return rel.string();
}

// A path value: a non-empty string without control characters, resolved against the
// session folder; a folder where a file is expected is refused here already.
std::string path_value(const YamlField& f, const Where& w, const std::string& expected) {
  const std::string text = f.as_string("a file path (" + expected + ")");
  for (const char ch : text) {
    if (static_cast<unsigned char>(ch) < 0x20) f.fail("expected a file path (" + expected + ")");
  }
  const std::string path = resolve(w, text);
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    f.fail("which names the folder " + path + ", expected " + expected);
  }
  return path;
}

std::string path_key(const YamlField& node, const std::string& key, const Where& w,
                     const std::string& expected) {
  return path_value(node.at(key, expected), w, expected);
}

RadiometrySpec read_radiometry(const YamlField& r) {
  RadiometrySpec spec;
  spec.source = r.file() + ": " + r.path();
  for (const auto& [k, v] : r.entries("a mapping {type: linear, kelvin_per_count: K, offset_k: K}")) {
    if (k == "type") {
      spec.type = v.as_string("a radiometry type (linear or planck)");
    } else {
      spec.parameters[k] = v.as_double("a finite number");
    }
  }
  return spec;
}

std::map<std::string, CameraEntry> read_cameras(const YamlField& root, const Where& w,
                                                bool mapping) {
  std::map<std::string, CameraEntry> cameras;
  const std::string expected = mapping ? "a mapping of camera name to {intrinsics: file.yaml, frames: index.csv}"
                                       : "a mapping of camera name to {intrinsics: file.yaml}";
  std::optional<YamlField> node = root.find("cameras");
  if (!node) {
    if (mapping) return cameras;  // a LIDAR-only map
    root.at("cameras", expected);
  }
  if (mapping && node->node().IsNull()) return cameras;
  for (const auto& [name, entry_node] : node->entries(expected)) {
    if (!is_valid_camera_name(name)) {
      entry_node.fail("camera name '" + name.substr(0, 80) +
                      "' is not usable, expected 1 to 64 characters of A-Z a-z 0-9 _ -");
    }
    entry_node.expect_map(mapping ? "{intrinsics: file.yaml, frames: index.csv}" : "{intrinsics: file.yaml}");
    CameraEntry entry;
    entry.intrinsics = path_key(entry_node, "intrinsics", w, "a camera_info YAML file");
    // A camera of a mapping session may have recorded nothing: `frames: ""` (what
    // `rgbdt_sim mapping --no-images` writes) keeps it with an empty frames path, and it
    // colours nothing. A missing key is still an error: the contract names the index.
    if (mapping) {
      const YamlField frames = entry_node.at("frames", "a CSV time index file (time_s,file)");
      if (!frames.as_string("a CSV time index file (time_s,file) or \"\"", true).empty()) {
        entry.frames = path_value(frames, w, "a CSV time index file (time_s,file)");
      }
    }
    if (const auto r = entry_node.find("radiometry")) entry.radiometry = read_radiometry(*r);
    cameras[name] = entry;
  }
  return cameras;
}

TargetSpec read_target(const YamlField& root) {
  TargetSpec t;
  const YamlField target = root.at("target", "{type: circle_hole, radius: METRES}");
  target.expect_map("{type: circle_hole, radius: METRES}");
  const YamlField type = target.at("type", "circle_hole");
  t.type = type.as_string("circle_hole");
  if (t.type != "circle_hole") type.fail("target type is not supported (expected circle_hole)");
  const YamlField radius = target.at("radius", "the hole radius in metres");
  t.radius_m = radius.as_double("a positive radius in metres");
  if (!(t.radius_m > 0.0 && t.radius_m <= kMaxTargetRadiusM)) {
    radius.fail("expected a positive radius in (0, " + std::to_string(kMaxTargetRadiusM).substr(0, 3) + "] m");
  }
  if (const auto holes = target.find("holes")) {
    const std::size_t n = holes->expect_sequence("a list of [x, y] hole centres in metres", kMaxHoles);
    for (std::size_t i = 0; i < n; ++i) {
      const auto xy = holes->item(i).as_numbers(2, "a hole centre [x, y] in metres");
      if (!(std::abs(xy[0]) <= kMaxBoardSideM && std::abs(xy[1]) <= kMaxBoardSideM)) {
        holes->item(i).fail("expected a hole centre within " + std::to_string(static_cast<int>(kMaxBoardSideM)) + " m of the board centre");
      }
      t.holes_m.emplace_back(xy[0], xy[1]);
    }
  }
  if (const auto board = target.find("board_size")) {
    const auto b = board->as_numbers(2, "[width, height] in metres");
    if (!(b[0] > 0.0 && b[1] > 0.0 && b[0] <= kMaxBoardSideM && b[1] <= kMaxBoardSideM)) {
      board->fail("expected [width, height] each in (0, " + std::to_string(static_cast<int>(kMaxBoardSideM)) + "] m");
    }
    t.board_size_m = Eigen::Vector2d(b[0], b[1]);
    const std::vector<Eigen::Vector2d> holes =
        t.holes_m.empty() ? std::vector<Eigen::Vector2d>{Eigen::Vector2d::Zero()} : t.holes_m;
    for (std::size_t i = 0; i < holes.size(); ++i) {
      const Eigen::Vector2d& h = holes[i];
      if (std::abs(h.x()) + t.radius_m > 0.5 * b[0] || std::abs(h.y()) + t.radius_m > 0.5 * b[1]) {
        std::ostringstream os;
        os << "expected a board larger than its holes: hole " << i << " at (" << h.x() << ", "
           << h.y() << ") m with radius " << t.radius_m << " m does not fit";
        board->fail(os.str());
      }
    }
  }
  return t;
}

CalibrationSession parse_calibration(const YAML::Node& document, const Where& w) {
  const YamlField root(document, w.yaml_path);
  CalibrationSession s;
  s.directory = w.dir.string();
  s.target = read_target(root);
  s.cameras = read_cameras(root, w, false);

  const YamlField views = root.at("views", "a non-empty list of views");
  if (views.expect_sequence("a non-empty list of views {cloud, images}", kMaxViews) == 0) {
    views.fail("expected a non-empty list of views");
  }
  for (std::size_t i = 0; i < views.node().size(); ++i) {
    const YamlField v = views.item(i);
    v.expect_map("a view {cloud: file.pcd, images: {camera: file.png}}");
    CalibrationView view;
    view.cloud = path_key(v, "cloud", w, "a PCD point cloud file");
    const YamlField images = v.at("images", "a mapping camera -> image file");
    for (const auto& [cam, file] : images.entries("a mapping camera -> image file")) {
      if (!s.cameras.count(cam)) {
        file.fail("camera '" + cam.substr(0, 80) + "' is not under 'cameras' (expected one of the session's cameras)");
      }
      view.images[cam] = path_value(file, w, "a PNG image file");
    }
    if (const auto seeds = v.find("seeds")) {
      for (const auto& [k, seed] : seeds->entries("a mapping {camera: [u, v], lidar: [x, y, z]}")) {
        if (k == "lidar") {
          const auto p = seed.as_numbers(3, "a list of 3 numbers [x, y, z] in metres");
          if (!(Eigen::Vector3d(p[0], p[1], p[2]).norm() <= kMaxSeedRangeM)) {
            seed.fail("expected a point within " + std::to_string(static_cast<int>(kMaxSeedRangeM)) + " m of the LIDAR");
          }
          view.lidar_seed = Eigen::Vector3d(p[0], p[1], p[2]);
        } else {
          if (!s.cameras.count(k)) {
            seed.fail("camera '" + k.substr(0, 80) + "' is not under 'cameras' (expected 'lidar' or one of the session's cameras)");
          }
          const auto p = seed.as_numbers(2, "a list of 2 numbers [u, v] in pixels");
          view.image_seeds[k] = Eigen::Vector2d(p[0], p[1]);
        }
      }
    }
    s.views.push_back(std::move(view));
  }
  return s;
}

ImuStream read_imu(const YamlField& imu, const Where& w) {
  const std::string expected = "{samples: imu.csv, rotation_lidar_imu: [qx, qy, qz, qw]}";
  imu.expect_map(expected);
  ImuStream stream;
  stream.samples = path_key(imu, "samples", w, "a CSV of IMU samples (time_s,wx,wy,wz,ax,ay,az)");
  if (const auto q = imu.find("rotation_lidar_imu")) {
    const std::vector<double> v = q->as_numbers(4, "a unit quaternion [qx, qy, qz, qw]");
    const Eigen::Quaterniond rotation(v[3], v[0], v[1], v[2]);
    if (std::abs(rotation.norm() - 1.0) > 1e-3) {
      throw Error(w.yaml_path, "key 'imu.rotation_lidar_imu' has norm " + std::to_string(rotation.norm()) +
                                   ", expected a unit quaternion [qx, qy, qz, qw]");
    }
    stream.rotation_lidar_imu = rotation.normalized();
  }
  return stream;
}

MappingSession parse_mapping(const YAML::Node& document, const Where& w) {
  const YamlField root(document, w.yaml_path);
  MappingSession s;
  s.directory = w.dir.string();
  const YamlField lidar = root.at("lidar", "{rawlog: file.rawlog} or {clouds: clouds/index.csv}");
  lidar.expect_map("{rawlog: file.rawlog} or {clouds: clouds/index.csv}");
  if (lidar.has("rawlog")) s.lidar.rawlog = path_key(lidar, "rawlog", w, "an MRPT rawlog file");
  if (lidar.has("clouds")) s.lidar.clouds = path_key(lidar, "clouds", w, "a CSV time index of clouds (time_s,file)");
  if (lidar.has("rig")) s.lidar.rig = path_key(lidar, "rig", w, "a tilt_rig.yaml file");
  if (s.lidar.rawlog.empty() && s.lidar.clouds.empty()) {
    throw Error(w.yaml_path, "key 'lidar' has neither 'rawlog' nor 'clouds' (expected one)");
  }
  s.cameras = read_cameras(root, w, true);
  if (root.has("trajectory")) s.trajectory = path_key(root, "trajectory", w, "a CSV trajectory file");
  if (const auto imu = root.find("imu")) s.imu = read_imu(*imu, w);
  return s;
}

void emit_cameras(YAML::Emitter& out, const std::map<std::string, CameraEntry>& cameras,
                  const fs::path& dir, bool frames) {
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, cam] : cameras) {
    out << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "intrinsics" << YAML::Value << relative_to(dir, cam.intrinsics);
    if (frames) out << YAML::Key << "frames" << YAML::Value << (cam.frames.empty() ? std::string() : relative_to(dir, cam.frames));
    if (cam.radiometry) {
      out << YAML::Key << "radiometry" << YAML::Value << YAML::Flow << YAML::BeginMap;
      out << YAML::Key << "type" << YAML::Value << cam.radiometry->type;
      for (const auto& [k, v] : cam.radiometry->parameters) out << YAML::Key << k << YAML::Value << v;
      out << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
}

void save(const std::string& yaml_path, const YAML::Emitter& out) {
  if (!out.good()) throw Error(yaml_path, std::string("cannot format the session: ") + out.GetLastError());
  write_file_atomic(yaml_path, std::string(out.c_str()) + "\n");
}

// Problems with one file a session names; empty when it is a readable, non-empty file.
std::optional<std::string> file_problem(const std::string& path, const std::string& key,
                                        const std::string& expected) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  std::string problem;
  if (!fs::exists(st)) {
    problem = "does not exist";
  } else if (fs::is_directory(st)) {
    problem = "is a folder";
  } else if (!fs::is_regular_file(st)) {
    problem = "is not a regular file";
  } else if (fs::file_size(path, ec) == 0 || ec) {
    problem = "is empty";
  } else if (!std::ifstream(path, std::ios::binary)) {
    problem = "cannot be opened for reading";
  } else {
    return std::nullopt;
  }
  return path + ": " + problem + " (expected " + expected + ", named by " + key + ")";
}

// Checks an index and the files its rows name; `what` names the row files.
void check_index(const std::string& path, const std::string& key, const std::string& what,
                 bool need_rows, std::vector<std::string>& problems) {
  if (auto p = file_problem(path, key, "a CSV time index (time_s,file)")) {
    problems.push_back(*p);
    return;
  }
  std::vector<TimedFile> rows;
  try {
    rows = read_time_index(path);
  } catch (const Error& e) {
    problems.push_back(std::string(e.what()) + " (named by " + key + ")");
    return;
  }
  if (rows.empty() && need_rows) {
    problems.push_back(path + ": lists no rows, only its header (expected at least one " + what +
                       ", named by " + key + ")");
  }
  std::size_t missing = 0;
  constexpr std::size_t kListed = 5;
  for (const auto& row : rows) {
    if (auto p = file_problem(row.file, key + " (" + path + ")", what)) {
      if (++missing <= kListed) problems.push_back(*p);
    }
  }
  if (missing > kListed) {
    problems.push_back(path + ": " + std::to_string(missing - kListed) + " more rows name missing or unusable " +
                       what + " files (named by " + key + ")");
  }
}

void check_cameras(const std::map<std::string, CameraEntry>& cameras, bool mapping,
                   std::vector<std::string>& problems) {
  for (const auto& [name, cam] : cameras) {
    const std::string key = "cameras." + name;
    if (auto p = file_problem(cam.intrinsics, key + ".intrinsics", "a camera_info YAML file")) {
      problems.push_back(*p);
    } else {
      try {
        read_camera_info(cam.intrinsics);
      } catch (const Error& e) {
        problems.push_back(std::string(e.what()) + " (named by " + key + ".intrinsics)");
      }
    }
    if (mapping && !cam.frames.empty()) check_index(cam.frames, key + ".frames", "image (PNG)", false, problems);
  }
}

}  // namespace

bool is_valid_camera_name(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char ch : name) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
                    ch == '_' || ch == '-';
    if (!ok) return false;
  }
  return true;
}

std::vector<std::string> preflight_problems(const CalibrationSession& s) {
  std::vector<std::string> problems;
  check_cameras(s.cameras, false, problems);
  for (std::size_t i = 0; i < s.views.size(); ++i) {
    const std::string key = "views[" + std::to_string(i) + "]";
    if (auto p = file_problem(s.views[i].cloud, key + ".cloud", "a PCD point cloud")) problems.push_back(*p);
    for (const auto& [cam, file] : s.views[i].images) {
      if (auto p = file_problem(file, key + ".images." + cam, "a PNG image")) problems.push_back(*p);
    }
  }
  return problems;
}

std::vector<std::string> preflight_problems(const MappingSession& s) {
  std::vector<std::string> problems;
  if (!s.lidar.rawlog.empty()) {
    if (auto p = file_problem(s.lidar.rawlog, "lidar.rawlog", "an MRPT rawlog")) problems.push_back(*p);
  }
  if (!s.lidar.clouds.empty()) check_index(s.lidar.clouds, "lidar.clouds", "PCD cloud", true, problems);
  if (!s.lidar.rig.empty()) {
    if (auto p = file_problem(s.lidar.rig, "lidar.rig", "a tilt_rig.yaml file")) {
      problems.push_back(*p);
    } else {
      try {
        read_tilt_rig(s.lidar.rig);
      } catch (const Error& e) {
        problems.push_back(std::string(e.what()) + " (named by lidar.rig)");
      }
    }
  }
  check_cameras(s.cameras, true, problems);
  if (!s.trajectory.empty()) {
    if (auto p = file_problem(s.trajectory, "trajectory", "a CSV trajectory")) problems.push_back(*p);
  }
  if (s.imu) {
    if (auto p = file_problem(s.imu->samples, "imu.samples", "a CSV of IMU samples")) problems.push_back(*p);
  }
  return problems;
}

CalibrationSession read_calibration_session(const std::string& path) {
  const Where w = locate(path);
  return parse_calibration(load_yaml_file(w.yaml_path), w);
}

CalibrationSession parse_calibration_session(const std::string& text, const std::string& yaml_path) {
  const Where w = place(yaml_path);
  return parse_calibration(load_yaml_string(text, w.yaml_path), w);
}

void write_calibration_session(const std::string& yaml_path, const CalibrationSession& s) {
  const fs::path dir = fs::absolute(fs::path(yaml_path)).parent_path();
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "target" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << s.target.type;
  out << YAML::Key << "radius" << YAML::Value << s.target.radius_m;
  if (s.target.board_size_m) {
    out << YAML::Key << "board_size" << YAML::Value << YAML::Flow << YAML::BeginSeq
        << s.target.board_size_m->x() << s.target.board_size_m->y() << YAML::EndSeq;
  }
  if (!s.target.holes_m.empty()) {
    out << YAML::Key << "holes" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const auto& h : s.target.holes_m) out << YAML::Flow << YAML::BeginSeq << h.x() << h.y() << YAML::EndSeq;
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
  emit_cameras(out, s.cameras, dir, false);
  out << YAML::Key << "views" << YAML::Value << YAML::BeginSeq;
  for (const auto& v : s.views) {
    out << YAML::BeginMap;
    out << YAML::Key << "cloud" << YAML::Value << relative_to(dir, v.cloud);
    out << YAML::Key << "images" << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (const auto& [cam, file] : v.images) out << YAML::Key << cam << YAML::Value << relative_to(dir, file);
    out << YAML::EndMap;
    if (!v.image_seeds.empty() || v.lidar_seed) {
      out << YAML::Key << "seeds" << YAML::Value << YAML::Flow << YAML::BeginMap;
      for (const auto& [cam, px] : v.image_seeds) {
        out << YAML::Key << cam << YAML::Value << YAML::Flow << YAML::BeginSeq << px.x() << px.y() << YAML::EndSeq;
      }
      if (v.lidar_seed) {
        out << YAML::Key << "lidar" << YAML::Value << YAML::Flow << YAML::BeginSeq << v.lidar_seed->x()
            << v.lidar_seed->y() << v.lidar_seed->z() << YAML::EndSeq;
      }
      out << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  save(yaml_path, out);
}

MappingSession read_mapping_session(const std::string& path) {
  const Where w = locate(path);
  return parse_mapping(load_yaml_file(w.yaml_path), w);
}

MappingSession parse_mapping_session(const std::string& text, const std::string& yaml_path) {
  const Where w = place(yaml_path);
  return parse_mapping(load_yaml_string(text, w.yaml_path), w);
}

void write_mapping_session(const std::string& yaml_path, const MappingSession& s) {
  const fs::path dir = fs::absolute(fs::path(yaml_path)).parent_path();
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "lidar" << YAML::Value << YAML::Flow << YAML::BeginMap;
  if (!s.lidar.rawlog.empty()) out << YAML::Key << "rawlog" << YAML::Value << relative_to(dir, s.lidar.rawlog);
  if (!s.lidar.clouds.empty()) out << YAML::Key << "clouds" << YAML::Value << relative_to(dir, s.lidar.clouds);
  if (!s.lidar.rig.empty()) out << YAML::Key << "rig" << YAML::Value << relative_to(dir, s.lidar.rig);
  out << YAML::EndMap;
  emit_cameras(out, s.cameras, dir, true);
  if (!s.trajectory.empty()) out << YAML::Key << "trajectory" << YAML::Value << relative_to(dir, s.trajectory);
  if (s.imu) {
    out << YAML::Key << "imu" << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "samples" << YAML::Value << relative_to(dir, s.imu->samples);
    if (!s.imu->rotation_lidar_imu.isApprox(Eigen::Quaterniond::Identity(), 1e-12)) {
      const Eigen::Quaterniond& q = s.imu->rotation_lidar_imu;
      out << YAML::Key << "rotation_lidar_imu" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.x() << q.y()
          << q.z() << q.w() << YAML::EndSeq;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  save(yaml_path, out);
}

}  // namespace rgbdt::core
