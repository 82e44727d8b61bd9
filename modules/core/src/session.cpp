#include "rgbdt/core/session.hpp"

#include <filesystem>
#include <fstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace fs = std::filesystem;

namespace rgbdt::core {
namespace {

struct Where {
  std::string yaml_path;
  fs::path dir;
};

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

std::string path_key(const YAML::Node& node, const std::string& key, const Where& w,
                     const std::string& context) {
  return resolve(w, require_string(node, key, w.yaml_path + " (" + context + ")"));
}

std::map<std::string, CameraEntry> read_cameras(const YAML::Node& root, const Where& w,
                                                bool need_frames) {
  std::map<std::string, CameraEntry> cameras;
  const YAML::Node node = require_key(root, "cameras", w.yaml_path,
                                      "a mapping of camera name to {intrinsics: file.yaml}");
  if (!node.IsMap()) throw Error(w.yaml_path, "key 'cameras' must be a mapping of camera names");
  for (const auto& kv : node) {
    const std::string name = kv.first.as<std::string>();
    const std::string ctx = "cameras." + name;
    CameraEntry entry;
    entry.intrinsics = path_key(kv.second, "intrinsics", w, ctx);
    if (need_frames) entry.frames = path_key(kv.second, "frames", w, ctx);
    if (kv.second["radiometry"]) {
      const YAML::Node r = kv.second["radiometry"];
      if (!r.IsMap()) throw Error(w.yaml_path, "key '" + ctx + ".radiometry' must be a mapping");
      RadiometrySpec spec;
      for (const auto& p : r) {
        const std::string k = p.first.as<std::string>();
        if (k == "type") {
          spec.type = require_string(r, "type", w.yaml_path + " (" + ctx + ".radiometry)");
        } else {
          spec.parameters[k] = require_double(r, k, w.yaml_path + " (" + ctx + ".radiometry)");
        }
      }
      entry.radiometry = spec;
    }
    cameras[name] = entry;
  }
  return cameras;
}

void emit_cameras(YAML::Emitter& out, const std::map<std::string, CameraEntry>& cameras,
                  const fs::path& dir, bool frames) {
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, cam] : cameras) {
    out << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "intrinsics" << YAML::Value << relative_to(dir, cam.intrinsics);
    if (frames) out << YAML::Key << "frames" << YAML::Value << relative_to(dir, cam.frames);
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
  std::ofstream f(yaml_path);
  if (!f) throw Error(yaml_path, "cannot open file for writing");
  f << out.c_str() << "\n";
  if (!f) throw Error(yaml_path, "write failed");
}

}  // namespace

CalibrationSession read_calibration_session(const std::string& path) {
  const Where w = locate(path);
  const YAML::Node root = load_yaml_file(w.yaml_path);
  CalibrationSession s;
  s.directory = w.dir.string();

  const YAML::Node target = require_key(root, "target", w.yaml_path,
                                        "{type: circle_hole, radius: METRES}");
  const std::string tsrc = w.yaml_path + " (target)";
  s.target.type = require_string(target, "type", tsrc);
  if (s.target.type != "circle_hole") {
    throw Error(w.yaml_path, "target type '" + s.target.type + "' is not supported (expected circle_hole)");
  }
  s.target.radius_m = require_double(target, "radius", tsrc);
  if (!(s.target.radius_m > 0.0)) {
    throw Error(w.yaml_path, "target radius " + std::to_string(s.target.radius_m) +
                                 " must be positive (metres)");
  }
  if (target["board_size"]) {
    const auto b = require_numbers(target, "board_size", tsrc, 2);
    s.target.board_size_m = Eigen::Vector2d(b[0], b[1]);
  }
  if (target["holes"]) {
    const YAML::Node holes = target["holes"];
    if (!holes.IsSequence()) throw Error(tsrc, "key 'holes' must be a list of [x, y] pairs");
    for (size_t i = 0; i < holes.size(); ++i) {
      YAML::Node wrap;
      wrap["hole"] = holes[i];
      const auto xy = require_numbers(wrap, "hole", tsrc + " holes[" + std::to_string(i) + "]", 2);
      s.target.holes_m.emplace_back(xy[0], xy[1]);
    }
  }

  s.cameras = read_cameras(root, w, false);

  const YAML::Node views = require_key(root, "views", w.yaml_path, "a list of views");
  if (!views.IsSequence() || views.size() == 0) {
    throw Error(w.yaml_path, "key 'views' must be a non-empty list");
  }
  for (size_t i = 0; i < views.size(); ++i) {
    const std::string ctx = "views[" + std::to_string(i) + "]";
    const YAML::Node v = views[i];
    CalibrationView view;
    view.cloud = path_key(v, "cloud", w, ctx);
    const YAML::Node images = require_key(v, "images", w.yaml_path + " (" + ctx + ")",
                                          "a mapping camera -> image file");
    for (const auto& kv : images) {
      const std::string cam = kv.first.as<std::string>();
      if (!s.cameras.count(cam)) {
        throw Error(w.yaml_path, ctx + ".images names camera '" + cam +
                                     "', which is not under 'cameras'");
      }
      view.images[cam] = path_key(images, cam, w, ctx + ".images");
    }
    if (v["seeds"]) {
      const YAML::Node seeds = v["seeds"];
      for (const auto& kv : seeds) {
        const std::string k = kv.first.as<std::string>();
        const std::string src = w.yaml_path + " (" + ctx + ".seeds)";
        if (k == "lidar") {
          const auto p = require_numbers(seeds, k, src, 3);
          view.lidar_seed = Eigen::Vector3d(p[0], p[1], p[2]);
        } else {
          const auto p = require_numbers(seeds, k, src, 2);
          view.image_seeds[k] = Eigen::Vector2d(p[0], p[1]);
        }
      }
    }
    s.views.push_back(std::move(view));
  }
  return s;
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
  const YAML::Node root = load_yaml_file(w.yaml_path);
  MappingSession s;
  s.directory = w.dir.string();
  const YAML::Node lidar = require_key(root, "lidar", w.yaml_path,
                                       "{rawlog: file.rawlog} or {clouds: clouds/index.csv}");
  if (lidar["rawlog"]) s.lidar.rawlog = path_key(lidar, "rawlog", w, "lidar");
  if (lidar["clouds"]) s.lidar.clouds = path_key(lidar, "clouds", w, "lidar");
  if (lidar["rig"]) s.lidar.rig = path_key(lidar, "rig", w, "lidar");
  if (s.lidar.rawlog.empty() && s.lidar.clouds.empty()) {
    throw Error(w.yaml_path, "key 'lidar' has neither 'rawlog' nor 'clouds' (expected one)");
  }
  s.cameras = read_cameras(root, w, true);
  if (root["trajectory"]) s.trajectory = resolve(w, require_string(root, "trajectory", w.yaml_path));
  return s;
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
  out << YAML::EndMap;
  save(yaml_path, out);
}

}  // namespace rgbdt::core
