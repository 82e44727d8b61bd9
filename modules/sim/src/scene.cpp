#include "rgbdt/sim/scene.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace rgbdt::sim {

namespace {

bool in_unit(double v) { return v >= 0.0 && v <= 1.0; }

// Smallest root of a s^2 + 2 b s + c = 0 inside (lo, hi], or the larger one.
bool solve_quadratic(double a, double b, double c, double lo, double hi, double* s_out) {
  if (std::abs(a) < 1e-15) return false;
  const double disc = b * b - a * c;
  if (disc < 0.0) return false;
  const double root = std::sqrt(disc);
  for (const double s : {(-b - root) / a, (-b + root) / a}) {
    if (s > lo && s <= hi) {
      *s_out = s;
      return true;
    }
  }
  return false;
}

}  // namespace

std::string Material::validate() const {
  std::ostringstream os;
  if (!in_unit(albedo_rgb.x()) || !in_unit(albedo_rgb.y()) || !in_unit(albedo_rgb.z())) {
    os << "material '" << name << "': albedo_rgb must be in [0, 1]";
  } else if (!(temperature_k > 0.0)) {
    os << "material '" << name << "': temperature_k " << temperature_k << " must be positive";
  } else if (!in_unit(emissivity)) {
    os << "material '" << name << "': emissivity " << emissivity << " must be in [0, 1]";
  } else if (!in_unit(nir_reflectivity)) {
    os << "material '" << name << "': nir_reflectivity " << nir_reflectivity << " must be in [0, 1]";
  } else if (!in_unit(lidar_dropout_probability)) {
    os << "material '" << name << "': lidar_dropout_probability " << lidar_dropout_probability
       << " must be in [0, 1]";
  }
  return os.str();
}

int Scene::add_material(const Material& material) {
  const std::string why = material.validate();
  if (!why.empty()) throw std::invalid_argument(why);
  materials_.push_back(material);
  return static_cast<int>(materials_.size()) - 1;
}

void Scene::check_material(int material, const char* what) const {
  if (material < 0 || material >= static_cast<int>(materials_.size())) {
    throw std::invalid_argument(std::string(what) + ": material index " + std::to_string(material) +
                                " is not one of the " + std::to_string(materials_.size()) + " materials added");
  }
}

int Scene::add_plane(const Eigen::Vector3d& point_world, const Eigen::Vector3d& normal_world, int material) {
  check_material(material, "add_plane");
  if (normal_world.norm() < 1e-12) throw std::invalid_argument("add_plane: normal must not be zero");
  Primitive p;
  p.kind = Kind::kPlane;
  p.material = material;
  // Local frame: origin on the plane, z along the normal.
  const Eigen::Vector3d n = normal_world.normalized();
  p.T_world_local.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n).toRotationMatrix();
  p.T_world_local.translation() = point_world;
  p.T_local_world = p.T_world_local.inverse();
  primitives_.push_back(p);
  return primitive_count() - 1;
}

int Scene::add_box(const Eigen::Isometry3d& T_world_box, const Eigen::Vector3d& half_extents_m, int material) {
  check_material(material, "add_box");
  if (!(half_extents_m.minCoeff() > 0.0)) throw std::invalid_argument("add_box: half extents must be positive");
  Primitive p;
  p.kind = Kind::kBox;
  p.material = material;
  p.T_world_local = T_world_box;
  p.T_local_world = T_world_box.inverse();
  p.extent = half_extents_m;
  p.bound_center = T_world_box.translation();
  p.bound_radius = half_extents_m.norm();
  primitives_.push_back(p);
  return primitive_count() - 1;
}

int Scene::add_board(const BoardSpec& board) {
  check_material(board.material, "add_board");
  if (!(board.size_m.minCoeff() > 0.0)) throw std::invalid_argument("add_board: size_m must be positive");
  if (!board.holes_m.empty() && !(board.hole_radius_m > 0.0)) {
    throw std::invalid_argument("add_board: hole_radius_m " + std::to_string(board.hole_radius_m) +
                                " must be positive when the board has holes");
  }
  if (board.squares_x > 0) {
    check_material(board.dark_material, "add_board (dark squares)");
    if (board.squares_y <= 0 || !(board.square_m > 0.0)) {
      throw std::invalid_argument("add_board: a checkerboard needs squares_y > 0 and square_m > 0");
    }
  }
  Primitive p;
  p.kind = Kind::kBoard;
  p.material = board.material;
  p.T_world_local = board.T_world_board;
  p.T_local_world = board.T_world_board.inverse();
  p.board = board;
  p.bound_center = board.T_world_board.translation();
  p.bound_radius = 0.5 * board.size_m.norm();
  primitives_.push_back(p);
  return primitive_count() - 1;
}

int Scene::add_cylinder(const Eigen::Vector3d& base_center_world, double radius_m, double height_m, int material) {
  check_material(material, "add_cylinder");
  if (!(radius_m > 0.0) || !(height_m > 0.0)) throw std::invalid_argument("add_cylinder: radius and height must be positive");
  Primitive p;
  p.kind = Kind::kCylinder;
  p.material = material;
  p.T_world_local.translation() = base_center_world;
  p.T_local_world = p.T_world_local.inverse();
  p.extent = {radius_m, height_m, 0.0};
  p.bound_center = base_center_world + Eigen::Vector3d(0, 0, 0.5 * height_m);
  p.bound_radius = std::hypot(radius_m, 0.5 * height_m);
  primitives_.push_back(p);
  return primitive_count() - 1;
}

int Scene::add_sphere(const Eigen::Vector3d& center_world, double radius_m, int material) {
  check_material(material, "add_sphere");
  if (!(radius_m > 0.0)) throw std::invalid_argument("add_sphere: radius must be positive");
  Primitive p;
  p.kind = Kind::kSphere;
  p.material = material;
  p.T_world_local.translation() = center_world;
  p.T_local_world = p.T_world_local.inverse();
  p.extent = {radius_m, 0.0, 0.0};
  p.bound_center = center_world;
  p.bound_radius = radius_m;
  primitives_.push_back(p);
  return primitive_count() - 1;
}

bool Scene::intersect_one(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double lo,
                          double hi, Hit* hit) const {
  if (p.kind != Kind::kPlane) {
    // Bounding-sphere rejection keeps scenes of many primitives cheap.
    const Eigen::Vector3d oc = p.bound_center - o;
    const double along = oc.dot(d);
    if (along + p.bound_radius < lo || along - p.bound_radius > hi) return false;
    if ((oc - along * d).squaredNorm() > p.bound_radius * p.bound_radius) return false;
  }
  const Eigen::Vector3d ol = p.T_local_world * o;
  const Eigen::Vector3d dl = p.T_local_world.linear() * d;
  double s = 0.0;
  Eigen::Vector3d n_local = Eigen::Vector3d::UnitZ();
  int material = p.material;
  int region = 0;
  switch (p.kind) {
    case Kind::kPlane: {
      if (std::abs(dl.z()) < 1e-15) return false;
      s = -ol.z() / dl.z();
      if (!(s > lo && s <= hi)) return false;
      n_local = Eigen::Vector3d::UnitZ();
      break;
    }
    case Kind::kBoard: {
      if (std::abs(dl.z()) < 1e-15) return false;
      s = -ol.z() / dl.z();
      if (!(s > lo && s <= hi)) return false;
      const double x = ol.x() + s * dl.x();
      const double y = ol.y() + s * dl.y();
      const BoardSpec& b = p.board;
      if (std::abs(x) > 0.5 * b.size_m.x() || std::abs(y) > 0.5 * b.size_m.y()) return false;
      const double r2 = b.hole_radius_m * b.hole_radius_m;
      for (const auto& c : b.holes_m) {
        if ((x - c.x()) * (x - c.x()) + (y - c.y()) * (y - c.y()) < r2) return false;
      }
      if (b.squares_x > 0) {
        const double col = std::floor((x - b.pattern_top_left_m.x()) / b.square_m);
        const double row = std::floor((b.pattern_top_left_m.y() - y) / b.square_m);
        if (col >= 0 && row >= 0 && col < b.squares_x && row < b.squares_y) {
          const bool dark = (static_cast<long>(col) + static_cast<long>(row)) % 2 == 0;
          material = dark ? b.dark_material : b.material;
          region = dark ? 1 : 2;
        }
      }
      n_local = Eigen::Vector3d::UnitZ();
      break;
    }
    case Kind::kBox: {
      double t0 = lo, t1 = hi;
      int axis0 = -1;
      for (int a = 0; a < 3; ++a) {
        const double e = p.extent[a];
        if (std::abs(dl[a]) < 1e-15) {
          if (std::abs(ol[a]) > e) return false;
          continue;
        }
        double ta = (-e - ol[a]) / dl[a];
        double tb = (e - ol[a]) / dl[a];
        if (ta > tb) std::swap(ta, tb);
        if (ta > t0) {
          t0 = ta;
          axis0 = a;
        }
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
      }
      if (axis0 < 0) return false;  // origin inside the box: not a visible surface
      s = t0;
      n_local = Eigen::Vector3d::Zero();
      n_local[axis0] = 1.0;
      break;
    }
    case Kind::kCylinder: {
      const double r = p.extent.x(), h = p.extent.y();
      bool found = false;
      double best = hi;
      // Side: x^2 + y^2 = r^2 with 0 <= z <= h.
      const double a = dl.x() * dl.x() + dl.y() * dl.y();
      const double b = ol.x() * dl.x() + ol.y() * dl.y();
      const double c = ol.x() * ol.x() + ol.y() * ol.y() - r * r;
      const double disc = b * b - a * c;
      if (a > 1e-15 && disc >= 0.0) {
        const double root = std::sqrt(disc);
        for (const double sc : {(-b - root) / a, (-b + root) / a}) {
          const double z = ol.z() + sc * dl.z();
          if (sc > lo && sc <= best && z >= 0.0 && z <= h) {
            best = sc;
            found = true;
            const Eigen::Vector3d q = ol + sc * dl;
            n_local = Eigen::Vector3d(q.x(), q.y(), 0.0) / r;
            break;
          }
        }
      }
      // Caps.
      if (std::abs(dl.z()) > 1e-15) {
        for (const double zc : {0.0, h}) {
          const double sc = (zc - ol.z()) / dl.z();
          const Eigen::Vector3d q = ol + sc * dl;
          if (sc > lo && sc <= best && q.x() * q.x() + q.y() * q.y() <= r * r) {
            best = sc;
            found = true;
            n_local = Eigen::Vector3d::UnitZ();
          }
        }
      }
      if (!found) return false;
      s = best;
      break;
    }
    case Kind::kSphere: {
      const double r = p.extent.x();
      if (!solve_quadratic(dl.squaredNorm(), ol.dot(dl), ol.squaredNorm() - r * r, lo, hi, &s)) return false;
      n_local = (ol + s * dl) / r;
      break;
    }
  }
  hit->distance = s;
  hit->point = o + s * d;
  Eigen::Vector3d n = p.T_world_local.linear() * n_local;
  if (n.dot(d) > 0.0) n = -n;
  hit->normal = n;
  hit->material = material;
  hit->region = region;
  return true;
}

std::optional<Hit> Scene::intersect(const Eigen::Vector3d& origin_world, const Eigen::Vector3d& direction_world,
                                    double min_distance_m, double max_distance_m) const {
  const double len = direction_world.norm();
  if (!(len > 0.0)) return std::nullopt;
  const Eigen::Vector3d d = direction_world / len;
  Hit best;
  bool found = false;
  double hi = max_distance_m;
  for (size_t i = 0; i < primitives_.size(); ++i) {
    Hit h;
    if (intersect_one(primitives_[i], origin_world, d, min_distance_m, hi, &h)) {
      best = h;
      best.primitive = static_cast<int>(i);
      hi = h.distance;
      found = true;
    }
  }
  if (!found) return std::nullopt;
  return best;
}

namespace {
Material make(const std::string& name, Eigen::Vector3d rgb, double t_k, double eps, double nir, double drop = 0.0) {
  Material m;
  m.name = name;
  m.albedo_rgb = rgb;
  m.temperature_k = t_k;
  m.emissivity = eps;
  m.nir_reflectivity = nir;
  m.lidar_dropout_probability = drop;
  return m;
}
}  // namespace

MaterialPresets material_presets(TimeOfDay time_of_day) {
  const bool day = time_of_day == TimeOfDay::kDay;
  const double air = day ? 295.0 : 284.0;
  MaterialPresets m;
  m.white_board = make("white_board", {0.85, 0.85, 0.83}, air + (day ? 1.5 : -0.5), 0.90, 0.80);
  // Evaporation keeps the wet cloth a few kelvin below the air; wet black fabric returns
  // little 905 nm light and loses many LIDAR returns.
  m.black_cloth = make("wet_black_cloth", {0.04, 0.04, 0.045}, air - (day ? 6.0 : 3.0), 0.97, 0.06, 0.25);
  // In the sun the black melamine absorbs more and is warmer than the white (paper Sec. 3.1).
  m.melamine_white = make("melamine_white", {0.88, 0.88, 0.88}, air + (day ? 4.0 : 0.5), 0.92, 0.85);
  m.melamine_black = make("melamine_black", {0.05, 0.05, 0.05}, air + (day ? 12.0 : 1.0), 0.92, 0.08);
  m.pavement = make("pavement", {0.32, 0.32, 0.33}, day ? 318.0 : 287.0, 0.95, 0.25);
  m.grass = make("grass", {0.20, 0.42, 0.15}, day ? 300.0 : 280.0, 0.98, 0.55);
  m.wall = make("wall", {0.72, 0.62, 0.52}, day ? 303.0 : 291.0, 0.93, 0.50);
  m.roof = make("roof", {0.45, 0.18, 0.15}, day ? 320.0 : 282.0, 0.92, 0.35);
  m.tree_trunk = make("tree_trunk", {0.30, 0.22, 0.15}, air, 0.96, 0.40);
  m.foliage = make("foliage", {0.15, 0.38, 0.12}, air - (day ? 1.0 : 0.5), 0.98, 0.60);
  m.car = make("car", {0.60, 0.08, 0.08}, day ? 312.0 : 286.0, 0.85, 0.45);
  return m;
}

Environment environment_preset(TimeOfDay time_of_day) {
  Environment e;
  if (time_of_day == TimeOfDay::kNight) {
    e.sun_irradiance = 0.0;
    e.ambient = 0.06;  // street lights
    e.sky_rgb = {0.02, 0.02, 0.05};
    e.sky_temperature_k = 235.0;
  }
  return e;
}

}  // namespace rgbdt::sim
