// rgbdt_mapper: RGB-Depth-Thermal map of a mapping session (paper Sec. 5).
//
//   rgbdt_mapper SESSION --calib DIR --out OUT [--resolution 0.05]
//
// Registers the session's tilt clouds into a trajectory (GICP against a local map),
// colours every point from the RGB and thermal frames nearest in time (motion compensated,
// occlusion aware), accumulates a voxel map and writes:
//   OUT/map.ply map.pcd                 coloured points with temperature [K]
//   OUT/map.bt                          OctoMap occupancy (ray-inserted, free space known)
//   OUT/map_rgb.ot map_thermal.ot       ColorOcTree and ThermalOcTree
//   OUT/trajectory.csv                  time_s,x,y,z,qx,qy,qz,qw of T_world_lidar
//   OUT/render_{rgb,thermal}_{top,perspective}.png
//   OUT/summary.json                    counts, coloured fractions, stage times, trajectory error
#include <CLI/CLI.hpp>
#include <yaml-cpp/yaml.h>

#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/rgbdt_map/colorize.hpp"
#include "rgbdt/rgbdt_map/export.hpp"
#include "rgbdt/rgbdt_map/registration.hpp"
#include "rgbdt/rgbdt_map/render.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"
#include "rgbdt/rgbdt_map/voxel_map.hpp"

namespace fs = std::filesystem;
using namespace rgbdt;
using namespace rgbdt::rgbdt_map;

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Camera {
  Camera(std::string camera_name, MappedCamera camera) : name(std::move(camera_name)), mapped(std::move(camera)) {}
  std::string name;
  MappedCamera mapped;
  std::vector<core::TimedFile> frames;
  bool thermal = false;
  // Last image loaded (consecutive clouds often share a frame).
  std::string loaded_path;
  cv::Mat image;
  // Statistics.
  std::size_t colored = 0, occluded = 0, in_view = 0;

  const cv::Mat& load(const std::string& path) {
    if (path != loaded_path) {
      image = cv::imread(path, thermal ? cv::IMREAD_ANYDEPTH : cv::IMREAD_COLOR);
      if (image.empty()) throw core::Error(path, "cannot read image (expected a PNG)");
      loaded_path = path;
    }
    return image;
  }
};

std::vector<float> thermal_lut(const core::CameraEntry& entry, const std::string& session) {
  if (!entry.radiometry) {
    throw core::Error(session, "camera 'thermal' has no radiometry (expected radiometry: {type: linear, "
                               "kelvin_per_count: K, offset_k: K})");
  }
  const core::RadiometrySpec& spec = *entry.radiometry;
  if (spec.type != "linear") {
    throw core::Error(session, "thermal radiometry type '" + spec.type + "' is not supported by rgbdt_mapper yet "
                               "(expected 'linear')");
  }
  auto parameter = [&](const std::string& key, std::optional<double> fallback) {
    const auto it = spec.parameters.find(key);
    if (it != spec.parameters.end()) return it->second;
    if (fallback) return *fallback;
    throw core::Error(session, "linear radiometry lacks '" + key + "'");
  };
  return linear_thermal_lut(parameter("kelvin_per_count", std::nullopt), parameter("offset_k", 0.0));
}

/// The trajectory of ground_truth.yaml (simulated sessions), if any.
std::optional<Trajectory> ground_truth_trajectory(const std::string& session_dir) {
  const fs::path yaml = fs::path(session_dir) / "ground_truth.yaml";
  if (!fs::exists(yaml)) return std::nullopt;
  const YAML::Node root = YAML::LoadFile(yaml.string());
  if (!root["trajectory"]) return std::nullopt;
  fs::path csv = root["trajectory"].as<std::string>();
  if (csv.is_relative()) csv = fs::path(session_dir) / csv;
  return read_trajectory_csv(csv.string());
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream os;
  os << std::setprecision(6) << v;
  return os.str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "rgbdt_mapper: builds an RGB-Depth-Thermal map from a mapping session.\n"
      "Registers the tilt clouds (GICP), colours each point from the RGB and thermal frames\n"
      "nearest in time (motion compensated; points the camera cannot see stay uncoloured),\n"
      "and writes map.ply, map.pcd, map.bt, map_rgb.ot, map_thermal.ot, trajectory.csv,\n"
      "PNG renders and summary.json into OUT."};
  std::string session_path, calib_dir, out_dir, backend = "gicp";
  double resolution_m = 0.05;
  int max_clouds = 0;
  app.add_option("session", session_path, "mapping session folder (or its session.yaml)")->required();
  app.add_option("--calib", calib_dir, "calibration folder with extrinsics_<camera>.yaml (e.g. SESSION/true_calib)")
      ->required();
  app.add_option("--out", out_dir, "output folder (created)")->required();
  app.add_option("--resolution", resolution_m, "map voxel and octree resolution [m]")->check(CLI::PositiveNumber);
  app.add_option("--icp", backend, "registration back-end: gicp or icp")->check(CLI::IsMember({"gicp", "icp"}));
  app.add_option("--max-clouds", max_clouds, "map only the first N clouds (0: all)");
  CLI11_PARSE(app, argc, argv);
  core::set_log_sink(core::stderr_log_sink);
  core::set_log_level(core::LogLevel::kWarning);

  try {
    const auto t_start = Clock::now();
    std::map<std::string, double> stage_s;
    const core::MappingSession session = core::read_mapping_session(session_path);
    if (session.lidar.clouds.empty()) {
      throw core::Error(session.directory, "lidar has no 'clouds' index; rgbdt_mapper reads assembled clouds "
                                           "(lidar: {clouds: clouds/index.csv})");
    }
    std::vector<core::TimedFile> clouds = core::read_time_index(session.lidar.clouds);
    if (max_clouds > 0 && static_cast<int>(clouds.size()) > max_clouds) clouds.resize(max_clouds);
    if (clouds.size() < 2) throw core::Error(session.lidar.clouds, "needs at least 2 clouds");

    std::vector<Camera> cameras;
    std::vector<float> lut_k;
    for (const auto& [name, entry] : session.cameras) {
      Camera camera(name, MappedCamera{core::PinholeCamera(core::read_camera_info(entry.intrinsics)),
                                       Eigen::Isometry3d::Identity()});
      const fs::path extrinsics = fs::path(calib_dir) / ("extrinsics_" + name + ".yaml");
      camera.mapped.T_camera_lidar = core::read_extrinsics(extrinsics.string()).T_parent_child;
      camera.frames = core::read_time_index(entry.frames);
      camera.thermal = name == "thermal" || entry.radiometry.has_value();
      if (camera.thermal) lut_k = thermal_lut(entry, session.directory);
      cameras.push_back(std::move(camera));
    }
    fs::create_directories(out_dir);
    std::printf("rgbdt_mapper: %zu clouds, cameras:", clouds.size());
    for (const auto& c : cameras) std::printf(" %s (%zu frames)", c.name.c_str(), c.frames.size());
    std::printf("\n");

    // Stage 1: registration.
    RegistrationOptions reg_options;
    reg_options.backend = icp_backend_from_string(backend);
    Odometry odometry(reg_options);
    auto t0 = Clock::now();
    std::size_t total_points = 0;
    double icp_ms = 0.0;
    for (std::size_t k = 0; k < clouds.size(); ++k) {
      const cloud::LoadedCloud loaded = cloud::load_pcd(clouds[k].file);
      total_points += loaded.cloud->size();
      const Odometry::Step step = odometry.add(*loaded.cloud, clouds[k].time_s);
      icp_ms += step.registration.time_ms;
      if (k % 10 == 0 || k + 1 == clouds.size()) {
        const Eigen::Vector3d p = step.T_world_lidar.translation();
        std::printf("[register %zu/%zu] t=%.2f s  %zu points  pose (%.2f, %.2f, %.2f) m  icp %.0f ms\n", k + 1,
                    clouds.size(), clouds[k].time_s, loaded.cloud->size(), p.x(), p.y(), p.z(),
                    step.registration.time_ms);
        std::fflush(stdout);
      }
    }
    stage_s["registration"] = seconds_since(t0);
    const Trajectory& trajectory = odometry.trajectory();
    write_trajectory_csv((fs::path(out_dir) / "trajectory.csv").string(), trajectory);

    // Stage 2: colouring, voxel map, occupancy.
    t0 = Clock::now();
    VoxelMap map({resolution_m});
    const int layer = map.add_thermal_layer(fs::path(session.directory).filename().string());
    OccupancyOptions occupancy_options;
    occupancy_options.resolution_m = resolution_m;
    OccupancyMapBuilder occupancy(occupancy_options);
    double colorize_s = 0.0, occupancy_s = 0.0;
    for (std::size_t k = 0; k < clouds.size(); ++k) {
      const cloud::LoadedCloud loaded = cloud::load_pcd(clouds[k].file);
      const cloud::Cloud& cloud = *loaded.cloud;
      float t_max = 0.0f;
      for (const auto& p : cloud) t_max = std::max(t_max, p.t);
      const double mid_time_s = clouds[k].time_s + 0.5 * t_max;

      const auto tc = Clock::now();
      std::optional<RgbColors> rgb;
      std::optional<Temperatures> temps;
      for (Camera& camera : cameras) {
        const int frame = core::nearest_in_time(camera.frames, mid_time_s);
        if (frame < 0) continue;
        const core::TimedFile& file = camera.frames[frame];
        const CameraProjection projection = project_with_occlusion(
            cloud, loaded.has_ring && loaded.has_t, clouds[k].time_s, camera.mapped, file.time_s, &trajectory);
        for (const ColorStatus s : projection.status) {
          camera.in_view += s == ColorStatus::kColored || s == ColorStatus::kOccluded;
          camera.occluded += s == ColorStatus::kOccluded;
        }
        if (camera.thermal) {
          temps = sample_temperature(projection, camera.load(file.file), lut_k);
          camera.colored += temps->colored;
        } else if (!rgb) {
          rgb = sample_rgb(projection, camera.load(file.file));
          camera.colored += rgb->colored;
        }
      }
      const std::vector<Eigen::Vector3f> world = points_in_world(cloud, clouds[k].time_s, trajectory);
      map.insert(world, rgb ? &*rgb : nullptr, temps ? &*temps : nullptr, layer, mid_time_s);
      colorize_s += seconds_since(tc);

      // Ray insertion from where the sensor was: one origin per 100 ms of the tilt (the
      // cart moves ~0.1 m in that time, below the free-space precision that matters).
      const auto to = Clock::now();
      constexpr double kChunkS = 0.1;
      std::map<long long, std::vector<Eigen::Vector3f>> chunks;
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        chunks[static_cast<long long>(cloud[i].t / kChunkS)].push_back(world[i]);
      }
      for (const auto& [chunk, points] : chunks) {
        const double t = clouds[k].time_s + (chunk + 0.5) * kChunkS;
        occupancy.insert_scan(points, trajectory.pose_at(t).translation());
      }
      occupancy_s += seconds_since(to);
      if (k % 10 == 0 || k + 1 == clouds.size()) {
        std::printf("[map %zu/%zu] %zu voxels\n", k + 1, clouds.size(), map.size());
        std::fflush(stdout);
      }
    }
    stage_s["colorize_and_map"] = colorize_s;
    stage_s["octomap_occupancy"] = occupancy_s;

    // Stage 3: files.
    t0 = Clock::now();
    const std::vector<MapPoint> points = map.points(layer);
    const fs::path out(out_dir);
    write_ply((out / "map.ply").string(), points);
    write_pcd((out / "map.pcd").string(), points);
    stage_s["export_ply_pcd"] = seconds_since(t0);
    t0 = Clock::now();
    occupancy.write_bt((out / "map.bt").string());
    write_color_octree((out / "map_rgb.ot").string(), points, resolution_m);
    write_thermal_octree((out / "map_thermal.ot").string(), points, resolution_m);
    stage_s["export_octomap"] = seconds_since(t0);
    t0 = Clock::now();
    RenderOptions render_options;
    render_options.voxel_size_m = resolution_m;
    for (const auto& [mode, name] : {std::pair{RenderMode::kRgb, "rgb"}, std::pair{RenderMode::kThermal, "thermal"}}) {
      const std::string base = (out / ("render_" + std::string(name))).string();
      if (!cv::imwrite(base + "_top.png", render_top_view(points, mode, render_options)) ||
          !cv::imwrite(base + "_perspective.png", render_perspective(points, mode, render_options))) {
        throw core::Error(base + "_*.png", "cannot write PNG");
      }
    }
    stage_s["render"] = seconds_since(t0);

    std::optional<double> rmse;
    if (auto truth = ground_truth_trajectory(session.directory)) {
      rmse = trajectory_rmse_m(trajectory, *truth);
    } else if (!session.trajectory.empty()) {
      rmse = trajectory_rmse_m(trajectory, read_trajectory_csv(session.trajectory));
    }

    // Summary.
    std::ostringstream json;
    json << "{\n  \"clouds\": " << clouds.size() << ",\n  \"points\": " << total_points
         << ",\n  \"voxels\": " << map.size() << ",\n  \"resolution_m\": " << json_number(resolution_m)
         << ",\n  \"icp_backend\": \"" << backend << "\",\n  \"icp_mean_ms\": "
         << json_number(icp_ms / std::max<std::size_t>(1, clouds.size() - 1));
    double rgb_fraction = NAN;
    for (const Camera& c : cameras) {
      const double fraction = static_cast<double>(c.colored) / std::max<std::size_t>(1, total_points);
      const double in_view = static_cast<double>(c.colored) / std::max<std::size_t>(1, c.in_view);
      if (!c.thermal && std::isnan(rgb_fraction)) rgb_fraction = fraction;
      json << ",\n  \"" << c.name << "\": {\"colored_points\": " << c.colored << ", \"colored_fraction\": "
           << json_number(fraction) << ", \"colored_fraction_in_view\": " << json_number(in_view)
           << ", \"occluded_points\": " << c.occluded << "}";
    }
    json << ",\n  \"colored_fraction\": " << json_number(rgb_fraction);
    json << ",\n  \"trajectory_rmse_m\": " << (rmse ? json_number(*rmse) : "null");
    json << ",\n  \"time_s\": {";
    bool first = true;
    for (const auto& [stage, s] : stage_s) {
      json << (first ? "" : ", ") << "\"" << stage << "\": " << json_number(s);
      first = false;
    }
    json << ", \"total\": " << json_number(seconds_since(t_start)) << "}\n}\n";
    std::ofstream((out / "summary.json").string()) << json.str();

    std::printf("\n%s", json.str().c_str());
    std::printf("\nwrote %s/{map.ply, map.pcd, map.bt, map_rgb.ot, map_thermal.ot, trajectory.csv, render_*.png, "
                "summary.json}\n",
                out_dir.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgbdt_mapper: error: %s\n", e.what());
    return 1;
  }
}
