#pragma once
/// \file
/// Scenes for the rig simulator: primitives (planes, boxes, boards with circular holes or
/// a checkerboard pattern, vertical cylinders, spheres) with materials, and ray casting.
///
/// The world frame is the scene's own frame (for calibration sessions it is the LIDAR
/// frame of the static rig). Every primitive is hit from both sides.
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

namespace rgbdt::sim {

/// What a surface looks like to each sensor.
struct Material {
  std::string name = "grey";
  Eigen::Vector3d albedo_rgb{0.5, 0.5, 0.5};  ///< visible reflectance per channel, [0, 1]
  double temperature_k = 293.15;              ///< surface temperature [K]
  double emissivity = 0.95;                   ///< long-wave infrared emissivity, [0, 1]
  double nir_reflectivity = 0.5;              ///< 905 nm reflectivity (LIDAR intensity), [0, 1]
  /// Probability that the LIDAR gets no return at all from this surface (wet or dark
  /// surfaces scatter the beam away), on top of the weak-signal dropouts of the LIDAR model.
  double lidar_dropout_probability = 0.0;

  std::string validate() const;  ///< empty when valid, else the reason
};

/// Scene-wide light and sky.
struct Environment {
  /// Towards the sun (normalised when used); by default low and behind the rig, which
  /// looks along +x, so the fronts of targets are lit.
  Eigen::Vector3d sun_direction_world{-0.6, 0.35, 0.72};
  double sun_irradiance = 0.7;    ///< diffuse gain of a surface facing the sun
  double ambient = 0.4;           ///< diffuse gain from the sky dome
  Eigen::Vector3d sky_rgb{0.62, 0.75, 0.92};  ///< colour of rays that hit nothing, [0, 1]
  double sky_temperature_k = 250.0;  ///< apparent temperature of the sky (and reflected sky)
};

/// A thin flat board in its own frame: origin at the board centre, x right, y up, z
/// towards the sensors (the frame of ground_truth.yaml's T_lidar_board). The board spans
/// |x| <= width/2, |y| <= height/2 in the plane z = 0, minus its circular holes. An
/// optional checkerboard pattern of squares alternates `material` (light) and
/// `dark_material`.
struct BoardSpec {
  Eigen::Isometry3d T_world_board = Eigen::Isometry3d::Identity();
  Eigen::Vector2d size_m{1.2, 1.2};          ///< width, height [m]
  std::vector<Eigen::Vector2d> holes_m;       ///< hole centres in the board frame [m]
  double hole_radius_m = 0.0;                 ///< [m]
  int material = 0;
  // Checkerboard (squares_x == 0: none). Square (0, 0) is the top-left one as seen from
  // the sensors, it is dark; the pattern starts at pattern_top_left_m.
  int squares_x = 0, squares_y = 0;           ///< squares across and down
  double square_m = 0.0508;                   ///< side of a square [m] (2 inches, the paper's)
  Eigen::Vector2d pattern_top_left_m{0.0, 0.0};  ///< board-frame corner of the pattern [m]
  int dark_material = -1;
};

/// Result of a ray cast.
struct Hit {
  double distance = 0.0;     ///< along the (unit) ray [m]
  Eigen::Vector3d point;     ///< world frame [m]
  Eigen::Vector3d normal;    ///< unit, facing the ray origin
  int primitive = -1;        ///< index of the primitive
  int material = -1;         ///< index into Scene::materials()
  int region = 0;            ///< sub-region within the primitive (checker colour), for edge finding
};

class Scene {
 public:
  /// Adds a material and returns its index. Throws std::invalid_argument if invalid.
  int add_material(const Material& material);
  /// Infinite plane through point with the given normal.
  int add_plane(const Eigen::Vector3d& point_world, const Eigen::Vector3d& normal_world, int material);
  /// Box with half extents along the axes of T_world_box.
  int add_box(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half_extents_m, int material);
  int add_board(const BoardSpec& board);
  /// Cylinder whose axis is world z, from base_center_world up by height_m (a tree trunk).
  int add_cylinder(const Eigen::Vector3d& base_center_world, double radius_m, double height_m, int material);
  int add_sphere(const Eigen::Vector3d& center_world, double radius_m, int material);

  /// Nearest hit along origin + s * direction for s in (min_distance, max_distance];
  /// direction need not be unit (it is normalised). Thread-safe (const).
  std::optional<Hit> intersect(const Eigen::Vector3d& origin_world, const Eigen::Vector3d& direction_world,
                               double min_distance_m = 1e-6, double max_distance_m = 1e6) const;

  const std::vector<Material>& materials() const { return materials_; }
  const Material& material(int index) const { return materials_.at(static_cast<size_t>(index)); }
  int primitive_count() const { return static_cast<int>(primitives_.size()); }

  Environment environment;

 private:
  enum class Kind { kPlane, kBox, kBoard, kCylinder, kSphere };
  struct Primitive {
    Kind kind = Kind::kPlane;
    int material = 0;
    Eigen::Isometry3d T_world_local = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d T_local_world = Eigen::Isometry3d::Identity();
    Eigen::Vector3d extent = Eigen::Vector3d::Zero();  ///< box half extents; cylinder (r, h, 0); sphere (r, 0, 0)
    Eigen::Vector3d bound_center = Eigen::Vector3d::Zero();  ///< bounding sphere (not for planes)
    double bound_radius = 0.0;
    BoardSpec board;
  };
  void check_material(int material, const char* what) const;
  bool intersect_one(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double lo, double hi,
                     Hit* hit) const;

  std::vector<Material> materials_;
  std::vector<Primitive> primitives_;
};

/// Day or night presets of the material temperatures.
enum class TimeOfDay { kDay, kNight };

/// The materials the generators use, with temperatures for the time of day: sun-heated
/// pavement by day, cool wet cloth, walls that stay warm at night.
struct MaterialPresets {
  Material white_board;   ///< white cardboard of the circle target
  Material black_cloth;   ///< wet black cloth backdrop
  Material melamine_white, melamine_black;  ///< the paper's checkerboard squares
  Material pavement, grass, wall, roof, tree_trunk, foliage, car;
};
MaterialPresets material_presets(TimeOfDay time_of_day);
Environment environment_preset(TimeOfDay time_of_day);

}  // namespace rgbdt::sim
