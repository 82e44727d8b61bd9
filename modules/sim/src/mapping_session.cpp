#include "rgbdt/sim/mapping_session.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/lidar_sim.hpp"
#include "rgbdt/sim/rawlog.hpp"
#include "session_io.hpp"

namespace rgbdt::sim {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Isometry3d yaw_pose(double x, double y, double z, double yaw) {
  return core::make_transform(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix(), {x, y, z});
}

// Camera frames of one camera: renders at every 1/fps, stamped at the middle of the
// exposure, and writes NNNNN.png plus index.csv.
template <typename RenderFn>
int write_frames(const fs::path& dir, double t0, double duration, double fps, double exposure_s, RenderFn render) {
  detail::make_dirs(dir.string());
  std::vector<core::TimedFile> index;
  for (int j = 0;; ++j) {
    const double t = t0 + j / fps + 0.5 * exposure_s;
    if (t >= t0 + duration) break;
    const fs::path file = dir / (detail::index_name(j, 5) + ".png");
    detail::write_png(file.string(), render(t, j));
    index.push_back({t, file.string()});
  }
  core::write_time_index((dir / "index.csv").string(), index);
  return static_cast<int>(index.size());
}

core::RadiometrySpec linear_radiometry(const ThermalCameraOptions& o) {
  core::RadiometrySpec r;
  r.type = "linear";
  r.parameters["kelvin_per_count"] = o.kelvin_per_count;
  r.parameters["offset_k"] = o.offset_k;
  return r;
}

// Ground truth per beam (see MappingSessionResult): row = scan, column = beam, value =
// apparent temperature in units of kBeamKelvinPerUnit, 0 where the beam has no single true
// temperature. A 16-bit PNG keeps 0.01 K over 0-655 K and compresses the piecewise
// constant materials well.
constexpr double kBeamKelvinPerUnit = 0.01;
void write_beam_temperatures(const std::string& path, const core::ScannerSpec& scanner,
                             const std::vector<RawScan>& scans) {
  cv::Mat image(static_cast<int>(scans.size()), scanner.beams, CV_16UC1, cv::Scalar(0));
  for (size_t k = 0; k < scans.size(); ++k) {
    const RawScan& s = scans[k];
    auto* row = image.ptr<std::uint16_t>(static_cast<int>(k));
    for (int i = 0; i < scanner.beams && i < static_cast<int>(s.truth_temperature_k.size()); ++i) {
      const float t = s.truth_temperature_k[static_cast<size_t>(i)];
      if (!s.valid[static_cast<size_t>(i)] || !std::isfinite(t)) continue;
      row[i] = static_cast<std::uint16_t>(std::clamp(std::lround(t / kBeamKelvinPerUnit), 1L, 65535L));
    }
  }
  detail::write_png(path, image);
}

}  // namespace

Eigen::Isometry3d CartTrajectory::T_world_lidar(double t) const {
  const double tau = t - start_time_s;
  const double w = 2.0 * M_PI / weave_period_s;
  const double x = speed_m_s * tau;
  const double y = weave_amplitude_m * std::sin(w * tau);
  const double heading = std::atan2(weave_amplitude_m * w * std::cos(w * tau), speed_m_s);
  return yaw_pose(x, y, lidar_height_m, heading);
}

std::string MappingSessionOptions::validate() const {
  std::ostringstream os;
  if (!(duration_s > 0.0) || duration_s > 600.0) os << "duration " << duration_s << " s must be in (0, 600]";
  else if (!(noise_scale >= 0.0)) os << "noise " << noise_scale << " must be >= 0";
  else if (supersampling < 1 || supersampling > 32) os << "supersampling " << supersampling << " must be in [1, 32]";
  else if (!(trajectory.speed_m_s >= 0.0) || !(trajectory.weave_period_s > 0.0)) os << "trajectory speed must be >= 0 and weave period > 0";
  else if (!(trajectory.start_time_s > 0.0)) os << "start time " << trajectory.start_time_s << " s must be positive (MRPT)";
  else if (!(imu.rate_hz >= 0.0) || imu.rate_hz > 10000.0) os << "IMU rate " << imu.rate_hz << " Hz must be in [0, 10000]";
  else if (const std::string r = rig.validate(); !r.empty()) os << r;
  return os.str();
}

namespace {

/// imu.csv of an IMU in the LIDAR's axes riding the cart from t0 to t1: the true angular rate
/// (central difference of the rotation over 2 ms) and specific force (second difference of
/// the position over 20 ms, minus gravity, in the IMU's axes), plus the noise of `imu`.
void write_imu_samples(const std::string& path, const CartTrajectory& traj, double t0, double t1,
                       const SimImu& imu, double noise_scale, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d gyro_bias =
      noise_scale * imu.gyro_bias_sigma_rad_s * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  const double gyro_sigma = noise_scale * imu.gyro_noise_density * std::sqrt(imu.rate_hz);
  const double accel_sigma = noise_scale * imu.accel_noise_density * std::sqrt(imu.rate_hz);
  const Eigen::Vector3d gravity(0.0, 0.0, -9.80665);
  std::ostringstream csv;
  csv << "time_s,wx,wy,wz,ax,ay,az\n" << std::setprecision(15);
  for (long k = 0;; ++k) {
    const double t = t0 + static_cast<double>(k) / imu.rate_hz;
    if (t > t1 + 1e-9) break;
    constexpr double hr = 1e-3, hp = 1e-2;
    const Eigen::Matrix3d R = traj.T_world_lidar(t).linear();
    const Eigen::AngleAxisd turn(traj.T_world_lidar(t - hr).linear().transpose() *
                                 traj.T_world_lidar(t + hr).linear());
    Eigen::Vector3d w = turn.axis() * turn.angle() / (2.0 * hr);
    const Eigen::Vector3d a = (traj.T_world_lidar(t + hp).translation() - 2.0 * traj.T_world_lidar(t).translation() +
                               traj.T_world_lidar(t - hp).translation()) /
                              (hp * hp);
    Eigen::Vector3d f = R.transpose() * (a - gravity);
    for (int i = 0; i < 3; ++i) {
      w[i] += gyro_bias[i] + gyro_sigma * normal(rng);
      f[i] += accel_sigma * normal(rng);
    }
    csv << t << ',' << w.x() << ',' << w.y() << ',' << w.z() << ',' << f.x() << ',' << f.y() << ',' << f.z()
        << '\n';
  }
  detail::save_text(path, csv.str());
}

}  // namespace

Scene make_street_scene(double length_m, TimeOfDay time_of_day, std::uint64_t seed) {
  const MaterialPresets m = material_presets(time_of_day);
  Scene scene;
  scene.environment = environment_preset(time_of_day);
  const int pavement = scene.add_material(m.pavement);
  const int grass = scene.add_material(m.grass);
  const int wall = scene.add_material(m.wall);
  const int trunk = scene.add_material(m.tree_trunk);
  const int foliage = scene.add_material(m.foliage);
  const int car = scene.add_material(m.car);
  const int roof = scene.add_material(m.roof);
  std::mt19937_64 rng(seed * 2654435761ULL + 3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double x_begin = -15.0, x_end = length_m + 25.0, mid = 0.5 * (x_begin + x_end), half = 0.5 * (x_end - x_begin);

  scene.add_plane(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), pavement);
  for (const double side : {-1.0, 1.0}) {
    // Grass verge (a slab 2 cm high) between the road and the buildings.
    scene.add_box(yaw_pose(mid, side * 6.0, 0.01, 0.0), {half, 2.0, 0.01}, grass);
    // Buildings: blocks of varied length and height with gaps between them.
    for (double x = x_begin; x < x_end;) {
      const double len = 8.0 + 8.0 * u(rng), height = 5.0 + 7.0 * u(rng), depth = 6.0 + 4.0 * u(rng);
      const double front = 9.0 + 2.0 * u(rng);
      scene.add_box(yaw_pose(x + 0.5 * len, side * (front + 0.5 * depth), 0.5 * height, 0.0),
                    {0.5 * len, 0.5 * depth, 0.5 * height}, u(rng) < 0.2 ? roof : wall);
      x += len + 2.0 + 4.0 * u(rng);
    }
    // Trees on the verge: a trunk and a round crown.
    for (double x = x_begin + 3.0 * u(rng); x < x_end; x += 6.0 + 4.0 * u(rng)) {
      const double y = side * (5.5 + 1.0 * u(rng)), h = 2.0 + 1.5 * u(rng), r = 1.2 + 0.8 * u(rng);
      scene.add_cylinder({x, y, 0.0}, 0.12 + 0.12 * u(rng), h, trunk);
      scene.add_sphere({x, y, h + 0.7 * r}, r, foliage);
    }
    // Parked cars along the kerb.
    for (double x = x_begin + 5.0 * u(rng); x < x_end; x += 9.0 + 12.0 * u(rng)) {
      scene.add_box(yaw_pose(x, side * 3.3, 0.75, 0.05 * (u(rng) - 0.5)), {2.2, 0.9, 0.75}, car);
    }
  }
  return scene;
}

MappingSessionResult write_mapping_session(const std::string& out_dir, const MappingSessionOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("mapping session options: " + why);
  }
  const RigSpec rig = detail::scale_noise(options.rig, options.noise_scale);
  const fs::path dir = fs::absolute(out_dir);
  for (const char* sub : {"clouds", "ground_truth"}) detail::make_dirs((dir / sub).string());
  MappingSessionResult result;
  result.directory = dir.string();

  const CartTrajectory& traj = options.trajectory;
  const double t0 = traj.start_time_s, t1 = t0 + options.duration_s;
  const Scene scene = make_street_scene(traj.speed_m_s * options.duration_s + 5.0, options.time_of_day, options.seed);
  const PoseFunction pose = [&traj](double t) { return traj.T_world_lidar(t); };

  // LIDAR: raw stream, then one assembled cloud per complete tilt.
  TiltLidarOptions lidar = rig.lidar;
  lidar.profile.start_time_s = t0;
  TiltLidarSimulator simulator(lidar, options.seed * 1000003 + 1);
  const std::vector<RawScan> scans = simulator.scans(scene, t0, t1, pose);
  const std::vector<EncoderSample> encoder = simulator.encoder_samples(t0, t1);
  write_rawlog((dir / "lidar.rawlog").string(), lidar.rig.scanner, scans, encoder);
  core::write_tilt_rig((dir / "tilt_rig.yaml").string(), lidar.rig);
  result.scans = static_cast<int>(scans.size());
  write_beam_temperatures((dir / "ground_truth" / "beam_temperature.png").string(), lidar.rig.scanner, scans);
  result.encoder_samples = static_cast<int>(encoder.size());
  const size_t per_tilt = static_cast<size_t>(std::floor(lidar.profile.tilt_duration_s / lidar.rig.scanner.scan_period_s + 1e-9));
  std::vector<core::TimedFile> cloud_index;
  for (long k = 0; k <= lidar.profile.tilt_index(t1); ++k) {
    const std::vector<RawScan> tilt = scans_of_tilt(lidar, scans, k);
    if (tilt.size() < per_tilt) continue;  // incomplete tilt at the end
    const cloud::Cloud cloud = assemble_cloud(lidar, tilt);
    if (cloud.empty()) continue;
    // The index stamps a cloud at its first point (its t = 0).
    double t_first = tilt.front().time_s;
    for (const RawScan& s : tilt) {
      const auto it = std::find(s.valid.begin(), s.valid.end(), 1);
      if (it != s.valid.end()) {
        t_first = s.time_s + lidar.rig.scanner.beam_time_offset(static_cast<int>(it - s.valid.begin()));
        break;
      }
    }
    const fs::path file = dir / "clouds" / (detail::index_name(static_cast<int>(cloud_index.size()), 5) + ".pcd");
    cloud::save_pcd(file.string(), cloud, cloud::PcdFormat::kBinary);
    cloud_index.push_back({t_first, file.string()});
  }
  core::write_time_index((dir / "clouds" / "index.csv").string(), cloud_index);
  result.clouds = static_cast<int>(cloud_index.size());
  core::log_info("sim: mapping LIDAR: ", result.scans, " scans, ", result.encoder_samples, " encoder samples, ",
                 result.clouds, " clouds");

  // Cameras.
  detail::write_true_calibration(dir.string(), rig, "a mapping session");
  const Eigen::Isometry3d T_lidar_rgb = rig.T_rgb_lidar.inverse(), T_lidar_thermal = rig.T_thermal_lidar.inverse();
  if (options.write_images) {
    const CameraRenderer rgb_renderer{core::PinholeCamera(rig.rgb_intrinsics)};
    const CameraRenderer thermal_renderer{core::PinholeCamera(rig.thermal_intrinsics)};
    RgbCameraOptions rgb_options = rig.rgb;
    rgb_options.render.supersampling = options.supersampling;
    ThermalCameraOptions thermal_options = rig.thermal;
    thermal_options.render.supersampling = options.supersampling;
    std::mt19937_64 rgb_rng(options.seed * 1000003 + 2), thermal_rng(options.seed * 1000003 + 3);
    result.rgb_frames = write_frames(dir / "rgb", t0, options.duration_s, rig.rgb_fps, rgb_options.exposure_time_s,
                                     [&](double t, int) {
                                       return rgb_renderer.render_rgb(scene, traj.T_world_lidar(t) * T_lidar_rgb,
                                                                      rgb_options, rgb_rng);
                                     });
    core::log_info("sim: mapping RGB: ", result.rgb_frames, " frames");
    result.thermal_frames = write_frames(
        dir / "thermal", t0, options.duration_s, rig.thermal_fps, thermal_options.exposure_time_s, [&](double t, int) {
          return thermal_renderer.render_thermal(scene, traj.T_world_lidar(t) * T_lidar_thermal, thermal_options,
                                                 thermal_rng);
        });
    core::log_info("sim: mapping thermal: ", result.thermal_frames, " frames");
  }

  // Trajectory of T_world_lidar at 100 Hz.
  {
    std::ostringstream csv;
    csv << "time_s,x,y,z,qx,qy,qz,qw\n" << std::setprecision(15);
    for (int k = 0;; ++k) {
      const double t = t0 + 0.01 * k;
      if (t > t1 + 1e-9) break;
      const Eigen::Isometry3d T = traj.T_world_lidar(t);
      const Eigen::Quaterniond q(T.linear());
      csv << t << ',' << T.translation().x() << ',' << T.translation().y() << ',' << T.translation().z() << ','
          << q.x() << ',' << q.y() << ',' << q.z() << ',' << q.w() << '\n';
    }
    detail::save_text((dir / "ground_truth" / "trajectory.csv").string(), csv.str());
  }

  if (options.imu.rate_hz > 0.0) {
    write_imu_samples((dir / "imu.csv").string(), traj, t0, t1, options.imu, options.noise_scale,
                      options.seed * 1000003 + 4);
  }

  core::MappingSession session;
  session.directory = dir.string();
  if (options.imu.rate_hz > 0.0) session.imu = core::ImuStream{(dir / "imu.csv").string()};
  session.lidar.rawlog = (dir / "lidar.rawlog").string();
  session.lidar.rig = (dir / "tilt_rig.yaml").string();
  session.lidar.clouds = (dir / "clouds" / "index.csv").string();
  session.cameras["rgb"].intrinsics = (dir / "rgb.yaml").string();
  session.cameras["thermal"].intrinsics = (dir / "thermal.yaml").string();
  if (options.write_images) {
    session.cameras["rgb"].frames = (dir / "rgb" / "index.csv").string();
    session.cameras["thermal"].frames = (dir / "thermal" / "index.csv").string();
  }
  session.cameras["thermal"].radiometry = linear_radiometry(rig.thermal);
  session.trajectory = (dir / "ground_truth" / "trajectory.csv").string();
  core::write_mapping_session((dir / "session.yaml").string(), session);

  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  detail::emit_ground_truth_header(out, rig, "tilt_rig.yaml");
  out << YAML::Key << "trajectory" << YAML::Value << "ground_truth/trajectory.csv";
  // Scan k of the rawlog starts at first_scan_time_s + k * scan_period_s (every scan, valid
  // or not), so a point's time finds its row and beam.
  out << YAML::Key << "beam_temperature" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "image" << YAML::Value << "ground_truth/beam_temperature.png";
  out << YAML::Key << "kelvin_per_unit" << YAML::Value << kBeamKelvinPerUnit;
  out << YAML::Key << "first_scan_time_s" << YAML::Value << (scans.empty() ? t0 : scans.front().time_s);
  out << YAML::Key << "scan_period_s" << YAML::Value << lidar.rig.scanner.scan_period_s;
  out << YAML::Key << "steps_per_revolution" << YAML::Value << lidar.rig.scanner.steps_per_revolution;
  out << YAML::Key << "about" << YAML::Value
      << "16-bit PNG, row = scan, column = beam: apparent temperature [K] / kelvin_per_unit of the surface "
         "the beam hit; 0 = no return or a footprint on two materials (mixed pixel)";
  out << YAML::EndMap;
  out << YAML::Key << "world" << YAML::Value
      << "street along +x, ground z = 0; trajectory.csv holds T_world_lidar (cart at ~1 m/s)";
  out << YAML::EndMap;
  detail::save_yaml((dir / "ground_truth.yaml").string(), out);
  return result;
}

std::string ColoringSetupOptions::validate() const {
  std::ostringstream os;
  if (depths_m.empty()) os << "depths must not be empty";
  else if (!(card_size_m.minCoeff() > 0.0)) os << "card size must be positive";
  else if (!(noise_scale >= 0.0)) os << "noise " << noise_scale << " must be >= 0";
  else if (supersampling < 1 || supersampling > 32) os << "supersampling " << supersampling << " must be in [1, 32]";
  else if (!(tilt_duration_s > 0.0)) os << "tilt_duration_s must be positive";
  else if (!(tilt_half_range_deg > 1.0 && tilt_half_range_deg < 80.0)) os << "tilt_half_range_deg must be in (1, 80)";
  else if (const std::string r = rig.validate(); !r.empty()) os << r;
  for (const double d : depths_m) {
    if (os.str().empty() && !(d >= 1.0 && d <= 28.0)) os << "depth " << d << " m must be in [1, 28]";
  }
  return os.str();
}

MappingSessionResult write_coloring_setup(const std::string& out_dir, const ColoringSetupOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("coloring setup options: " + why);
  }
  const RigSpec rig = detail::scale_noise(options.rig, options.noise_scale);
  const fs::path dir = fs::absolute(out_dir);
  for (const char* sub : {"clouds", "rgb", "thermal"}) detail::make_dirs((dir / sub).string());
  MappingSessionResult result;
  result.directory = dir.string();
  const MaterialPresets m = material_presets(TimeOfDay::kDay);
  const CameraRenderer rgb_renderer{core::PinholeCamera(rig.rgb_intrinsics)};
  const CameraRenderer thermal_renderer{core::PinholeCamera(rig.thermal_intrinsics)};
  RgbCameraOptions rgb_options = rig.rgb;
  rgb_options.render.supersampling = options.supersampling;
  ThermalCameraOptions thermal_options = rig.thermal;
  thermal_options.render.supersampling = options.supersampling;

  std::vector<core::TimedFile> clouds, rgb_frames, thermal_frames;
  std::vector<Eigen::Isometry3d> card_poses;
  std::vector<double> times;
  for (size_t i = 0; i < options.depths_m.size(); ++i) {
    const double depth = options.depths_m[i];
    const double t = 100.0 + 10.0 * static_cast<double>(i);
    Scene scene;
    scene.environment = environment_preset(TimeOfDay::kDay);
    const int pavement = scene.add_material(m.pavement);
    const int white = scene.add_material(m.white_board);
    const int cloth = scene.add_material(m.black_cloth);
    scene.add_plane({0, 0, -1.1}, Eigen::Vector3d::UnitZ(), pavement);
    // Card straight ahead at the tilt axis' height, facing the rig; cloth 1 m behind.
    Eigen::Matrix3d R;
    R.col(0) = -Eigen::Vector3d::UnitY();
    R.col(1) = Eigen::Vector3d::UnitZ();
    R.col(2) = -Eigen::Vector3d::UnitX();
    const Eigen::Isometry3d T_lidar_card = core::make_transform(R, {depth, 0.0, 0.0});
    BoardSpec card;
    card.T_world_board = T_lidar_card;
    card.size_m = options.card_size_m;
    card.material = white;
    scene.add_board(card);
    BoardSpec backdrop;
    backdrop.T_world_board = core::make_transform(R, {depth + 1.0, 0.0, 0.0});
    backdrop.size_m = {options.card_size_m.x() + 2.0, options.card_size_m.y() + 1.6};
    backdrop.material = cloth;
    scene.add_board(backdrop);

    TiltLidarOptions lidar = rig.lidar;
    lidar.profile.phi_start_rad = -options.tilt_half_range_deg * kDeg;
    lidar.profile.phi_end_rad = options.tilt_half_range_deg * kDeg;
    lidar.profile.tilt_duration_s = options.tilt_duration_s;
    lidar.profile.start_time_s = t;
    TiltLidarSimulator simulator(lidar, options.seed * 1000003 + 10 * i);
    const auto identity = [](double) { return Eigen::Isometry3d::Identity(); };
    const cloud::Cloud cloud = assemble_cloud(lidar, simulator.scans(scene, t, t + options.tilt_duration_s, identity));
    const std::string name = detail::index_name(static_cast<int>(i), 5);
    clouds.push_back({t, (dir / "clouds" / (name + ".pcd")).string()});
    cloud::save_pcd(clouds.back().file, cloud, cloud::PcdFormat::kBinary);
    std::mt19937_64 rgb_rng(options.seed * 1000003 + 10 * i + 1), thermal_rng(options.seed * 1000003 + 10 * i + 2);
    rgb_frames.push_back({t, (dir / "rgb" / (name + ".png")).string()});
    detail::write_png(rgb_frames.back().file, rgb_renderer.render_rgb(scene, rig.T_rgb_lidar.inverse(), rgb_options, rgb_rng));
    thermal_frames.push_back({t, (dir / "thermal" / (name + ".png")).string()});
    detail::write_png(thermal_frames.back().file,
                      thermal_renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), thermal_options, thermal_rng));
    card_poses.push_back(T_lidar_card);
    times.push_back(t);
    core::log_info("sim: coloring setup at ", depth, " m: ", cloud.size(), " points");
  }
  core::write_time_index((dir / "clouds" / "index.csv").string(), clouds);
  core::write_time_index((dir / "rgb" / "index.csv").string(), rgb_frames);
  core::write_time_index((dir / "thermal" / "index.csv").string(), thermal_frames);
  result.clouds = static_cast<int>(clouds.size());
  result.rgb_frames = result.thermal_frames = static_cast<int>(clouds.size());

  detail::write_true_calibration(dir.string(), rig, "the coloring-error setup of paper Sec. 4.4");
  core::MappingSession session;
  session.directory = dir.string();
  session.lidar.clouds = (dir / "clouds" / "index.csv").string();
  session.cameras["rgb"] = {(dir / "rgb.yaml").string(), (dir / "rgb" / "index.csv").string(), std::nullopt};
  session.cameras["thermal"] = {(dir / "thermal.yaml").string(), (dir / "thermal" / "index.csv").string(),
                                linear_radiometry(rig.thermal)};
  core::write_mapping_session((dir / "session.yaml").string(), session);

  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  detail::emit_ground_truth_header(out, rig, "");
  out << YAML::Key << "coloring_setup" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "card_size" << YAML::Value << YAML::Flow << YAML::BeginSeq << options.card_size_m.x()
      << options.card_size_m.y() << YAML::EndSeq;
  out << YAML::Key << "views" << YAML::Value << YAML::BeginSeq;
  for (size_t i = 0; i < card_poses.size(); ++i) {
    const Eigen::Vector2d h = 0.5 * options.card_size_m;
    out << YAML::BeginMap;
    out << YAML::Key << "depth_m" << YAML::Value << options.depths_m[i];
    out << YAML::Key << "time_s" << YAML::Value << times[i];
    out << YAML::Key << "T_lidar_card" << YAML::Value;
    detail::emit_pose(out, card_poses[i]);
    // Corners top-left, top-right, bottom-right, bottom-left as seen from the sensors.
    out << YAML::Key << "corners_lidar" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(-h.x(), h.y()), Eigen::Vector2d(h.x(), h.y()),
                                     Eigen::Vector2d(h.x(), -h.y()), Eigen::Vector2d(-h.x(), -h.y())}) {
      detail::emit_vector(out, card_poses[i] * Eigen::Vector3d(c.x(), c.y(), 0.0));
    }
    out << YAML::EndSeq;
    out << YAML::Key << "normal_lidar" << YAML::Value;
    detail::emit_vector(out, card_poses[i].linear().col(2));
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap << YAML::EndMap;
  detail::save_yaml((dir / "ground_truth.yaml").string(), out);
  return result;
}

}  // namespace rgbdt::sim
