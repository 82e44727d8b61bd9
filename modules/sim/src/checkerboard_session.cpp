#include "rgbdt/sim/checkerboard_session.hpp"

#include <cmath>
#include <filesystem>
#include <random>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/core/transform.hpp"
#include "session_io.hpp"

namespace rgbdt::sim {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;

bool is_thermal(const std::string& camera) { return camera == "thermal"; }

}  // namespace

std::string CheckerboardSessionOptions::validate() const {
  std::ostringstream os;
  if (camera != "rgb" && camera != "thermal") os << "camera '" << camera << "' must be rgb or thermal";
  else if (views < 0 || views > 1000) os << "views " << views << " must be in [0, 1000]";
  else if (squares_x < 3 || squares_y < 3) os << "squares " << squares_x << "x" << squares_y << " must be at least 3x3";
  else if (!(square_m > 0.0)) os << "square_m " << square_m << " must be positive";
  else if (!(noise_scale >= 0.0)) os << "noise " << noise_scale << " must be >= 0";
  else if (!(min_distance_m >= 0.0) || !(max_distance_m >= 0.0)) os << "distances must be >= 0";
  else if (!(max_tilt_deg >= 0.0 && max_tilt_deg < 70.0)) os << "max_tilt_deg " << max_tilt_deg << " must be in [0, 70)";
  else if (supersampling < 1 || supersampling > 32) os << "supersampling " << supersampling << " must be in [1, 32]";
  else if (const std::string r = rig.validate(); !r.empty()) os << r;
  return os.str();
}

std::vector<Eigen::Vector3d> checkerboard_corners(int squares_x, int squares_y, double square_m) {
  const double x0 = -0.5 * squares_x * square_m, y0 = 0.5 * squares_y * square_m;
  std::vector<Eigen::Vector3d> corners;
  for (int j = 0; j + 1 < squares_y; ++j) {
    for (int i = 0; i + 1 < squares_x; ++i) corners.emplace_back(x0 + (i + 1) * square_m, y0 - (j + 1) * square_m, 0.0);
  }
  return corners;
}

CheckerboardSessionResult write_checkerboard_session(const std::string& out_dir,
                                                     const CheckerboardSessionOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("checkerboard session options: " + why);
  }
  const bool thermal = is_thermal(options.camera);
  const RigSpec rig = detail::scale_noise(options.rig, options.noise_scale);
  const int views = options.views > 0 ? options.views : (thermal ? 40 : 20);
  const double d_min = options.min_distance_m > 0.0 ? options.min_distance_m : (thermal ? 0.7 : 1.0);
  const double d_max = options.max_distance_m > 0.0 ? options.max_distance_m : (thermal ? 1.6 : 2.2);
  if (d_max < d_min) throw std::invalid_argument("checkerboard session options: max distance below min distance");

  CheckerboardSessionResult result;
  result.directory = fs::absolute(out_dir).string();
  result.intrinsics = thermal ? rig.thermal_intrinsics : rig.rgb_intrinsics;
  const core::PinholeCamera camera(result.intrinsics);
  const CameraRenderer renderer(camera);
  const fs::path dir(result.directory);
  detail::make_dirs((dir / options.camera).string());
  detail::make_dirs((dir / "true_calib").string());

  const MaterialPresets m = material_presets(options.time_of_day);
  const double sq = options.square_m;
  const Eigen::Vector2d pattern(options.squares_x * sq, options.squares_y * sq);
  result.corners_board = checkerboard_corners(options.squares_x, options.squares_y, sq);
  // Margin of white melamine one square wide around the pattern: the quiet zone that
  // corner detectors expect around the outer squares.
  const Eigen::Vector2d board_size = pattern + Eigen::Vector2d(2 * sq, 2 * sq);

  std::mt19937_64 pose_rng(options.seed * 6151 + 17);
  std::uniform_real_distribution<double> uni(-1.0, 1.0), unit(0.0, 1.0);
  for (int i = 0; i < views; ++i) {
    Eigen::Isometry3d T_camera_board = Eigen::Isometry3d::Identity();
    bool found = false;
    for (int attempt = 0; attempt < 5000 && !found; ++attempt) {
      // Aim the board at a random image point so corners and edges of the image get covered.
      const Eigen::Vector2d aim(unit(pose_rng) * (camera.width() - 1), unit(pose_rng) * (camera.height() - 1));
      const double d = d_min + (d_max - d_min) * unit(pose_rng);
      const Eigen::Vector3d c = camera.unproject(aim).normalized() * d;
      // Fronto-parallel: board x = camera x, board y = -camera y, board z = -camera z.
      Eigen::Matrix3d R = Eigen::Vector3d(1, -1, -1).asDiagonal();
      const double tilt = options.max_tilt_deg * kDeg;
      R = R * Eigen::AngleAxisd(tilt * uni(pose_rng), Eigen::Vector3d::UnitY()).toRotationMatrix() *
          Eigen::AngleAxisd(tilt * uni(pose_rng), Eigen::Vector3d::UnitX()).toRotationMatrix() *
          Eigen::AngleAxisd(20.0 * kDeg * uni(pose_rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T_camera_board = core::make_transform(R, c);
      // The whole board (with its margin) inside the image, facing the camera.
      if (R.col(2).dot(-c.normalized()) < std::cos(60.0 * kDeg)) continue;
      found = true;
      for (const double sx : {-0.5, 0.5}) {
        for (const double sy : {-0.5, 0.5}) {
          Eigen::Vector2d px;
          const Eigen::Vector3d p = T_camera_board * Eigen::Vector3d(sx * board_size.x(), sy * board_size.y(), 0);
          if (!camera.project(p, &px) || !camera.in_image(px, 5.0)) found = false;
        }
      }
    }
    if (!found) throw std::invalid_argument("checkerboard session: no board pose fits the image; reduce the distance range");

    Scene scene;
    scene.environment = environment_preset(options.time_of_day);
    const int white = scene.add_material(m.melamine_white);
    const int black = scene.add_material(m.melamine_black);
    const int wall = scene.add_material(m.wall);
    BoardSpec board;
    board.T_world_board = T_camera_board;  // world = camera frame here
    board.size_m = board_size;
    board.material = white;
    board.dark_material = black;
    board.squares_x = options.squares_x;
    board.squares_y = options.squares_y;
    board.square_m = sq;
    board.pattern_top_left_m = Eigen::Vector2d(-0.5 * pattern.x(), 0.5 * pattern.y());
    scene.add_board(board);
    // A wall some metres behind the board (camera looks along +z).
    scene.add_plane({0, 0, d_max + 4.0}, -Eigen::Vector3d::UnitZ(), wall);
    // The sun lights the board from behind the camera.
    scene.environment.sun_direction_world = Eigen::Vector3d(0.3, -0.6, -0.75);

    std::mt19937_64 rng(options.seed * 1000003 + static_cast<std::uint64_t>(i));
    cv::Mat image;
    if (thermal) {
      ThermalCameraOptions o = rig.thermal;
      o.render.supersampling = options.supersampling;
      image = renderer.render_thermal(scene, Eigen::Isometry3d::Identity(), o, rng);
    } else {
      RgbCameraOptions o = rig.rgb;
      o.render.supersampling = options.supersampling;
      image = renderer.render_rgb(scene, Eigen::Isometry3d::Identity(), o, rng);
    }
    detail::write_png((dir / options.camera / (detail::index_name(i) + ".png")).string(), image);

    CheckerboardViewTruth truth;
    truth.T_camera_board = T_camera_board;
    for (const Eigen::Vector3d& p : result.corners_board) {
      Eigen::Vector2d px;
      camera.project(T_camera_board * p, &px);
      truth.corners_px.push_back(px);
    }
    result.views.push_back(truth);
    core::log_info("sim: checkerboard view ", i + 1, "/", views, " at ", T_camera_board.translation().norm(), " m");
  }

  core::write_camera_info((dir / (options.camera + ".yaml")).string(), result.intrinsics);
  core::write_camera_info((dir / "true_calib" / (options.camera + ".yaml")).string(), result.intrinsics);
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "camera" << YAML::Value << options.camera;
  out << YAML::Key << "intrinsics" << YAML::Value << ("true_calib/" + options.camera + ".yaml");
  out << YAML::Key << "board" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << "checkerboard";
  out << YAML::Key << "squares" << YAML::Value << YAML::Flow << YAML::BeginSeq << options.squares_x << options.squares_y
      << YAML::EndSeq;
  out << YAML::Key << "inner_corners" << YAML::Value << YAML::Flow << YAML::BeginSeq << options.squares_x - 1
      << options.squares_y - 1 << YAML::EndSeq;
  out << YAML::Key << "square_m" << YAML::Value << sq;
  out << YAML::Key << "board_size" << YAML::Value << YAML::Flow << YAML::BeginSeq << board_size.x() << board_size.y()
      << YAML::EndSeq;
  out << YAML::EndMap;
  if (thermal) {
    out << YAML::Key << "radiometry" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "type"
        << YAML::Value << "linear" << YAML::Key << "kelvin_per_count" << YAML::Value << rig.thermal.kelvin_per_count
        << YAML::Key << "offset_k" << YAML::Value << rig.thermal.offset_k << YAML::EndMap;
    out << YAML::Key << "netd_k" << YAML::Value << rig.thermal.netd_k;
  }
  out << YAML::Key << "views" << YAML::Value << YAML::BeginSeq;
  for (size_t i = 0; i < result.views.size(); ++i) {
    out << YAML::BeginMap;
    out << YAML::Key << "image" << YAML::Value << (options.camera + "/" + detail::index_name(static_cast<int>(i)) + ".png");
    out << YAML::Key << "T_camera_board" << YAML::Value;
    detail::emit_pose(out, result.views[i].T_camera_board);
    out << YAML::Key << "corners_px" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    for (const Eigen::Vector2d& c : result.views[i].corners_px) {
      out << YAML::Flow << YAML::BeginSeq << c.x() << c.y() << YAML::EndSeq;
    }
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  detail::save_yaml((dir / "ground_truth.yaml").string(), out);
  return result;
}

}  // namespace rgbdt::sim
