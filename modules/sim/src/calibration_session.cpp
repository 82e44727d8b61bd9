#include "rgbdt/sim/calibration_session.hpp"

#include <cmath>
#include <filesystem>
#include <random>
#include <sstream>
#include <stdexcept>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/sim/multibeam_sim.hpp"
#include "session_io.hpp"

namespace rgbdt::sim {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kLidarHeightM = 1.1;  // tilt axis above the ground
constexpr int kTargetPrimitive = 1;
constexpr int kClothPrimitive = 2;

std::vector<Eigen::Vector2d> hole_centers(const core::TargetSpec& target) {
  if (target.holes_m.empty()) return {Eigen::Vector2d::Zero()};
  return target.holes_m;
}

// Rotation whose z axis points from p towards the origin and whose y axis is as close to
// world up as possible: a board (or cloth) at p facing the sensors.
Eigen::Matrix3d facing_origin(const Eigen::Vector3d& p) {
  const Eigen::Vector3d z = -p.normalized();
  Eigen::Vector3d y = Eigen::Vector3d::UnitZ() - z * z.z();
  y.normalize();
  Eigen::Matrix3d R;
  R.col(0) = y.cross(z);
  R.col(1) = y;
  R.col(2) = z;
  return R;
}

// Are all holes fully visible (inside the image, not occluded, the cloth behind them) in
// this camera, and does the board face it?
bool holes_visible(const Scene& scene, const core::TargetSpec& target, const Eigen::Isometry3d& T_lidar_board,
                   const core::PinholeCamera& camera, const Eigen::Isometry3d& T_camera_lidar) {
  constexpr double kMarginPx = 12.0;
  const Eigen::Isometry3d T_lidar_camera = T_camera_lidar.inverse();
  const Eigen::Vector3d cam = T_lidar_camera.translation();
  const Eigen::Vector3d normal = T_lidar_board.linear().col(2);
  const Eigen::Vector3d to_cam = (cam - T_lidar_board.translation()).normalized();
  if (normal.dot(to_cam) < std::cos(65.0 * kDeg)) return false;
  for (const Eigen::Vector2d& c : hole_centers(target)) {
    for (int k = 0; k < 72; ++k) {
      const double a = k * 5.0 * kDeg;
      const Eigen::Vector2d dir(std::cos(a), std::sin(a));
      const Eigen::Vector3d edge = T_lidar_board * Eigen::Vector3d(c.x() + target.radius_m * dir.x(),
                                                                   c.y() + target.radius_m * dir.y(), 0.0);
      Eigen::Vector2d px;
      if (!camera.project(T_camera_lidar * edge, &px) || !camera.in_image(px, kMarginPx)) return false;
      for (const double f : {0.95, 1.05}) {
        const Eigen::Vector3d p =
            T_lidar_board * Eigen::Vector3d(c.x() + f * target.radius_m * dir.x(), c.y() + f * target.radius_m * dir.y(), 0.0);
        const std::optional<Hit> hit = scene.intersect(cam, p - cam);
        const int want = f < 1.0 ? kClothPrimitive : kTargetPrimitive;
        if (!hit || hit->primitive != want) return false;
        if (f > 1.0 && std::abs(hit->distance - (p - cam).norm()) > 1e-6) return false;
      }
    }
  }
  return true;
}

// Is the whole board inside the tilt sweep (with a margin) so every hole is scanned?
bool board_in_sweep(const core::TargetSpec& target, const Eigen::Isometry3d& T_lidar_board, const TiltProfile& profile) {
  const double lo = std::min(profile.phi_start_rad, profile.phi_end_rad) + 3.0 * kDeg;
  const double hi = std::max(profile.phi_start_rad, profile.phi_end_rad) - 3.0 * kDeg;
  const Eigen::Vector2d half = 0.5 * target.board_size_m.value_or(Eigen::Vector2d(1.2, 1.2));
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector3d p = T_lidar_board * Eigen::Vector3d(sx * half.x(), sy * half.y(), 0.0);
      // A point at elevation e in the x-z plane is on the scan plane when phi = -e.
      const double phi = -std::atan2(p.z(), p.x());
      if (phi < lo || phi > hi) return false;
    }
  }
  return true;
}


bool is_spinning(LidarKind k) {
  return k == LidarKind::kSpinning16 || k == LidarKind::kSpinning32 || k == LidarKind::kSpinning64;
}

int spinning_rings(LidarKind k) { return k == LidarKind::kSpinning16 ? 16 : k == LidarKind::kSpinning32 ? 32 : 64; }

// Half of the azimuth sector simulated for a spinning LIDAR: the board poses lie within
// +-10 deg of +x; the sector also covers the cloth and some ground around them.
constexpr double kSpinningHalfAzimuthRad = 40.0 * kDeg;

// Is the whole board (with a margin) where the LIDAR of `kind` looks, so every hole is scanned?
bool board_in_lidar_view(const CalibrationSessionOptions& options, const core::TargetSpec& target,
                         const Eigen::Isometry3d& T_lidar_board, const TiltProfile& profile) {
  if (options.lidar == LidarKind::kTilt) return board_in_sweep(target, T_lidar_board, profile);
  const Eigen::Vector2d half = 0.5 * target.board_size_m.value_or(Eigen::Vector2d(1.2, 1.2));
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector3d p = T_lidar_board * Eigen::Vector3d(sx * half.x(), sy * half.y(), 0.0);
      if (is_spinning(options.lidar)) {
        const SpinningLidarOptions s = SpinningLidarOptions::preset(spinning_rings(options.lidar));
        const double el = std::atan2(p.z(), std::hypot(p.x(), p.y())) / kDeg;
        if (el < s.fov_down_deg + 1.0 || el > s.fov_up_deg - 1.0) return false;
        if (std::abs(std::atan2(p.y(), p.x())) > kSpinningHalfAzimuthRad - 5.0 * kDeg) return false;
      } else {
        const double off_axis = std::acos(std::clamp(p.normalized().x(), -1.0, 1.0)) / kDeg;
        if (off_axis > 0.5 * DenseLidarOptions{}.fov_deg - 1.0) return false;
      }
    }
  }
  return true;
}

// Draws board poses until all holes are fully visible to both cameras and scanned by the LIDAR.
Eigen::Isometry3d draw_board_pose(const CalibrationSessionOptions& options, const core::TargetSpec& target,
                                  const RigSpec& rig, TiltLidarOptions* lidar, std::mt19937_64* pose_rng,
                                  int* attempts) {
  const core::PinholeCamera rgb_camera(rig.rgb_intrinsics);
  const core::PinholeCamera thermal_camera(rig.thermal_intrinsics);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::uniform_real_distribution<double> dist(options.min_distance_m, options.max_distance_m);
  for (int attempt = 0; attempt < 2000; ++attempt) {
    ++*attempts;
    const double d = dist(*pose_rng);
    const double az = 10.0 * kDeg * uni(*pose_rng);
    const double el = 6.0 * kDeg * uni(*pose_rng);
    const Eigen::Vector3d c = d * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    const Eigen::Matrix3d R = facing_origin(c) * Eigen::AngleAxisd(35.0 * kDeg * uni(*pose_rng), Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(20.0 * kDeg * uni(*pose_rng), Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(25.0 * kDeg * uni(*pose_rng), Eigen::Vector3d::UnitZ());
    const Eigen::Isometry3d T_lidar_board = core::make_transform(R, c);
    lidar->profile.start_time_s = options.start_time_s;
    if (!board_in_lidar_view(options, target, T_lidar_board, lidar->profile)) continue;
    const Scene scene = make_calibration_scene(target, T_lidar_board, options.cloth_gap_m, options.time_of_day);
    if (holes_visible(scene, target, T_lidar_board, rgb_camera, rig.T_rgb_lidar) &&
        holes_visible(scene, target, T_lidar_board, thermal_camera, rig.T_thermal_lidar)) {
      return T_lidar_board;
    }
  }
  throw std::invalid_argument("calibration session: no board pose with all holes visible in both cameras and the " +
                              to_string(options.lidar) + " LIDAR for distances [" + std::to_string(options.min_distance_m) +
                              ", " + std::to_string(options.max_distance_m) + "] m; use a smaller target or range");
}

// The LIDAR cloud of view i (board scene at time t_view) from the LIDAR of options.lidar.
cloud::Cloud simulate_view_cloud(const CalibrationSessionOptions& options, const TiltLidarOptions& lidar,
                                 const Scene& scene, int i, double t_view) {
  std::mt19937_64 lidar_rng_seed(options.seed * 1000003 + static_cast<std::uint64_t>(i) * 3 + 0);
  const double scale = options.noise_scale;
  if (options.lidar == LidarKind::kTilt) {
    TiltLidarOptions tilt = lidar;
    tilt.profile.start_time_s = t_view;
    if (options.range_noise_m >= 0.0) tilt.range_sigma_m = options.range_noise_m;
    TiltLidarSimulator simulator(tilt, lidar_rng_seed());
    const auto identity = [](double) { return Eigen::Isometry3d::Identity(); };
    return assemble_cloud(tilt, simulator.scans(scene, t_view, t_view + options.tilt_duration_s, identity));
  }
  if (is_spinning(options.lidar)) {
    SpinningLidarOptions s = SpinningLidarOptions::preset(spinning_rings(options.lidar));
    s.beam.range_sigma_m = options.range_noise_m >= 0.0 ? options.range_noise_m : scale * s.beam.range_sigma_m;
    if (!lidar.mixed_pixels) s.beam.divergence_rad = 0.0;
    return simulate_spinning(scene, s, kSpinningHalfAzimuthRad, lidar_rng_seed());
  }
  DenseLidarOptions d;
  d.duration_s = options.dense_duration_s;
  d.beam.range_sigma_m = options.range_noise_m >= 0.0 ? options.range_noise_m : scale * d.beam.range_sigma_m;
  if (!lidar.mixed_pixels) d.beam.divergence_rad = 0.0;
  return simulate_dense(scene, d, lidar_rng_seed());
}

TiltLidarOptions session_tilt_lidar(const CalibrationSessionOptions& options, const RigSpec& rig) {
  TiltLidarOptions lidar = rig.lidar;
  lidar.profile.phi_start_rad = -options.tilt_half_range_deg * kDeg;
  lidar.profile.phi_end_rad = options.tilt_half_range_deg * kDeg;
  lidar.profile.tilt_duration_s = options.tilt_duration_s;
  return lidar;
}

CalibrationViewTruth view_truth(const core::TargetSpec& target, const Eigen::Isometry3d& T_lidar_board, double t_view) {
  CalibrationViewTruth truth;
  truth.T_lidar_board = T_lidar_board;
  for (const Eigen::Vector2d& c : hole_centers(target)) {
    truth.hole_centers_lidar.push_back(T_lidar_board * Eigen::Vector3d(c.x(), c.y(), 0.0));
  }
  truth.normal_lidar = T_lidar_board.linear().col(2);
  truth.time_s = t_view;
  return truth;
}

}  // namespace

std::string CalibrationSessionOptions::validate() const {
  std::ostringstream os;
  if (views < 1 || views > 1000) os << "views " << views << " must be in [1, 1000]";
  else if (!(noise_scale >= 0.0)) os << "noise " << noise_scale << " must be >= 0";
  else if (holes != 1 && holes != 4) os << "holes " << holes << " must be 1 or 4";
  else if (!(hole_radius_m >= 0.0)) os << "hole_radius_m " << hole_radius_m << " must be >= 0";
  else if (!(min_distance_m >= 1.0) || !(max_distance_m >= min_distance_m) || max_distance_m > 25.0)
    os << "distance range [" << min_distance_m << ", " << max_distance_m << "] m must satisfy 1 <= min <= max <= 25";
  else if (!(cloth_gap_m > 0.05)) os << "cloth_gap_m " << cloth_gap_m << " must be > 0.05";
  else if (supersampling < 1 || supersampling > 32) os << "supersampling " << supersampling << " must be in [1, 32]";
  else if (!(tilt_duration_s > 0.0)) os << "tilt_duration_s " << tilt_duration_s << " must be positive";
  else if (!(tilt_half_range_deg > 5.0 && tilt_half_range_deg < 80.0))
    os << "tilt_half_range_deg " << tilt_half_range_deg << " must be in (5, 80)";
  else if (!(range_noise_m < 0.5)) os << "range_noise_m " << range_noise_m << " must be < 0.5 (< 0: the LIDAR's own)";
  else if (!(dense_duration_s > 0.0 && dense_duration_s <= 60.0))
    os << "dense_duration_s " << dense_duration_s << " must be in (0, 60]";
  else if (const std::string r = rig.validate(); !r.empty()) os << r;
  return os.str();
}

std::string to_string(LidarKind kind) {
  switch (kind) {
    case LidarKind::kTilt: return "tilt";
    case LidarKind::kSpinning16: return "spinning16";
    case LidarKind::kSpinning32: return "spinning32";
    case LidarKind::kSpinning64: return "spinning64";
    case LidarKind::kDense: return "dense";
  }
  return "unknown";
}

LidarKind lidar_kind_from_string(const std::string& name) {
  for (const LidarKind k : {LidarKind::kTilt, LidarKind::kSpinning16, LidarKind::kSpinning32, LidarKind::kSpinning64,
                            LidarKind::kDense}) {
    if (to_string(k) == name) return k;
  }
  throw std::invalid_argument("LIDAR kind '" + name + "' must be one of tilt, spinning16, spinning32, spinning64, dense");
}

std::vector<SimulatedLidarView> simulate_lidar_views(const CalibrationSessionOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("calibration session options: " + why);
  }
  const RigSpec rig = detail::scale_noise(options.rig, options.noise_scale);
  const core::TargetSpec target = calibration_target(options.holes, options.hole_radius_m);
  TiltLidarOptions lidar = session_tilt_lidar(options, rig);
  std::mt19937_64 pose_rng(options.seed * 7919 + 11);
  int attempts = 0;
  std::vector<SimulatedLidarView> out;
  for (int i = 0; i < options.views; ++i) {
    const Eigen::Isometry3d T_lidar_board = draw_board_pose(options, target, rig, &lidar, &pose_rng, &attempts);
    const Scene scene = make_calibration_scene(target, T_lidar_board, options.cloth_gap_m, options.time_of_day);
    const double t_view = options.start_time_s + 10.0 * i;
    SimulatedLidarView v;
    v.truth = view_truth(target, T_lidar_board, t_view);
    v.cloud = simulate_view_cloud(options, lidar, scene, i, t_view);
    v.has_ring = options.lidar != LidarKind::kDense;
    out.push_back(std::move(v));
  }
  return out;
}

core::TargetSpec calibration_target(int holes, double radius_m) {
  core::TargetSpec t;
  t.type = "circle_hole";
  if (holes == 1) {
    t.radius_m = radius_m > 0.0 ? radius_m : 0.30;
    const double side = std::max(1.2, 4.0 * t.radius_m);
    t.board_size_m = Eigen::Vector2d(side, side);
  } else if (holes == 4) {
    t.radius_m = radius_m > 0.0 ? radius_m : 0.12;
    const double dx = std::max(0.25, 2.0 * t.radius_m + 0.01), dy = std::max(0.2, 1.6 * t.radius_m + 0.01);
    t.board_size_m = Eigen::Vector2d(2.0 * dx + 4.0 * t.radius_m, 2.0 * dy + 4.0 * t.radius_m);
    // Row-major, top-left first as seen from the sensors (board x right, y up).
    t.holes_m = {{-dx, dy}, {dx, dy}, {-dx, -dy}, {dx, -dy}};
  } else {
    throw std::invalid_argument("calibration_target: holes " + std::to_string(holes) + " must be 1 or 4");
  }
  return t;
}

Scene make_calibration_scene(const core::TargetSpec& target, const Eigen::Isometry3d& T_lidar_board,
                             double cloth_gap_m, TimeOfDay time_of_day) {
  const MaterialPresets m = material_presets(time_of_day);
  Scene scene;
  scene.environment = environment_preset(time_of_day);
  const int pavement = scene.add_material(m.pavement);
  const int white = scene.add_material(m.white_board);
  const int cloth = scene.add_material(m.black_cloth);
  scene.add_plane({0.0, 0.0, -kLidarHeightM}, Eigen::Vector3d::UnitZ(), pavement);  // primitive 0
  BoardSpec board;
  board.T_world_board = T_lidar_board;
  board.size_m = target.board_size_m.value_or(Eigen::Vector2d(1.2, 1.2));
  board.holes_m = hole_centers(target);
  board.hole_radius_m = target.radius_m;
  board.material = white;
  scene.add_board(board);  // primitive 1 (kTargetPrimitive)
  // The cloth hangs on a rack behind the target, facing the sensors.
  const Eigen::Vector3d c = T_lidar_board.translation();
  BoardSpec backdrop;
  const Eigen::Vector3d centre = c + cloth_gap_m * c.normalized();
  backdrop.T_world_board.linear() = facing_origin(centre);
  backdrop.T_world_board.translation() = centre;
  backdrop.size_m = {2.2 + board.size_m.x(), 1.8 + board.size_m.y()};
  backdrop.material = cloth;
  scene.add_board(backdrop);  // primitive 2 (kClothPrimitive)
  return scene;
}

CalibrationSessionResult write_calibration_session(const std::string& out_dir,
                                                   const CalibrationSessionOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("calibration session options: " + why);
  }
  const RigSpec rig = detail::scale_noise(options.rig, options.noise_scale);
  const core::PinholeCamera rgb_camera(rig.rgb_intrinsics);
  const core::PinholeCamera thermal_camera(rig.thermal_intrinsics);
  const CameraRenderer rgb_renderer(rgb_camera);
  const CameraRenderer thermal_renderer(thermal_camera);

  const fs::path dir = fs::absolute(out_dir);
  for (const char* sub : {"clouds", "rgb", "thermal"}) detail::make_dirs((dir / sub).string());

  CalibrationSessionResult result;
  result.directory = dir.string();
  result.target = calibration_target(options.holes, options.hole_radius_m);
  const core::TargetSpec& target = result.target;

  TiltLidarOptions lidar = session_tilt_lidar(options, rig);
  std::mt19937_64 pose_rng(options.seed * 7919 + 11);

  core::CalibrationSession session;
  session.directory = dir.string();
  session.target = target;
  session.cameras["rgb"].intrinsics = (dir / "rgb.yaml").string();
  session.cameras["thermal"].intrinsics = (dir / "thermal.yaml").string();

  for (int i = 0; i < options.views; ++i) {
    const Eigen::Isometry3d T_lidar_board =
        draw_board_pose(options, target, rig, &lidar, &pose_rng, &result.pose_attempts);
    const Scene scene = make_calibration_scene(target, T_lidar_board, options.cloth_gap_m, options.time_of_day);
    const double t_view = options.start_time_s + 10.0 * i;  // the target is moved every 10 s
    lidar.profile.start_time_s = t_view;

    // Independent random streams per view and sensor: the same seed gives the same session.
    std::mt19937_64 rgb_rng(options.seed * 1000003 + static_cast<std::uint64_t>(i) * 3 + 1);
    std::mt19937_64 thermal_rng(options.seed * 1000003 + static_cast<std::uint64_t>(i) * 3 + 2);
    const cloud::Cloud cloud = simulate_view_cloud(options, lidar, scene, i, t_view);

    RgbCameraOptions rgb_options = rig.rgb;
    rgb_options.render.supersampling = options.supersampling;
    ThermalCameraOptions thermal_options = rig.thermal;
    thermal_options.render.supersampling = options.supersampling;
    const cv::Mat rgb = rgb_renderer.render_rgb(scene, rig.T_rgb_lidar.inverse(), rgb_options, rgb_rng);
    const cv::Mat thermal =
        thermal_renderer.render_thermal(scene, rig.T_thermal_lidar.inverse(), thermal_options, thermal_rng);

    const std::string name = detail::index_name(i);
    core::CalibrationView view;
    view.cloud = (dir / "clouds" / (name + ".pcd")).string();
    view.images["rgb"] = (dir / "rgb" / (name + ".png")).string();
    view.images["thermal"] = (dir / "thermal" / (name + ".png")).string();
    if (options.lidar == LidarKind::kDense) {
      save_pcd_without_ring(view.cloud, cloud);
    } else {
      cloud::save_pcd(view.cloud, cloud, cloud::PcdFormat::kBinary);
    }
    detail::write_png(view.images["rgb"], rgb);
    detail::write_png(view.images["thermal"], thermal);

    // Seeds as a user would click them: the board centre in the images, a point on the
    // board (beside the hole for a one-hole board) in the cloud.
    const Eigen::Vector3d centre = T_lidar_board.translation();
    Eigen::Vector2d px;
    if (rgb_camera.project(rig.T_rgb_lidar * centre, &px)) view.image_seeds["rgb"] = px;
    if (thermal_camera.project(rig.T_thermal_lidar * centre, &px)) view.image_seeds["thermal"] = px;
    const double board_half_h = 0.5 * target.board_size_m->y();
    const Eigen::Vector2d on_board =
        options.holes == 1 ? Eigen::Vector2d(0.0, -0.5 * (target.radius_m + board_half_h)) : Eigen::Vector2d::Zero();
    view.lidar_seed = T_lidar_board * Eigen::Vector3d(on_board.x(), on_board.y(), 0.0);
    session.views.push_back(view);

    const CalibrationViewTruth truth = view_truth(target, T_lidar_board, t_view);
    result.views.push_back(truth);
    core::log_info("sim: calibration view ", i + 1, "/", options.views, " at ", centre.norm(), " m, ", cloud.size(),
                   " points");
  }

  core::write_calibration_session((dir / "session.yaml").string(), session);
  detail::write_true_calibration(dir.string(), rig,
                                 "a calibration session (" + std::to_string(options.views) + " views, seed " +
                                     std::to_string(options.seed) + ")");
  core::TiltRig tilt_rig = lidar.rig;
  core::write_tilt_rig((dir / "tilt_rig.yaml").string(), tilt_rig);

  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  detail::emit_ground_truth_header(out, rig, "");
  out << YAML::Key << "target" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "radius" << YAML::Value << target.radius_m;
  out << YAML::Key << "board_size" << YAML::Value << YAML::Flow << YAML::BeginSeq << target.board_size_m->x()
      << target.board_size_m->y() << YAML::EndSeq;
  out << YAML::Key << "holes_board" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const Eigen::Vector2d& c : hole_centers(target)) out << YAML::Flow << YAML::BeginSeq << c.x() << c.y() << YAML::EndSeq;
  out << YAML::EndSeq;
  out << YAML::Key << "views" << YAML::Value << YAML::BeginSeq;
  for (const CalibrationViewTruth& v : result.views) {
    out << YAML::BeginMap;
    out << YAML::Key << "T_lidar_board" << YAML::Value;
    detail::emit_pose(out, v.T_lidar_board);
    out << YAML::Key << "hole_centers_lidar" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const Eigen::Vector3d& c : v.hole_centers_lidar) detail::emit_vector(out, c);
    out << YAML::EndSeq;
    out << YAML::Key << "normal_lidar" << YAML::Value;
    detail::emit_vector(out, v.normal_lidar);
    out << YAML::Key << "time_s" << YAML::Value << v.time_s;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  out << YAML::EndMap;
  detail::save_yaml((dir / "ground_truth.yaml").string(), out);
  return result;
}

}  // namespace rgbdt::sim
