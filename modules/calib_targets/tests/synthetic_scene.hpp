#pragma once
// Synthetic LIDAR scenes for the tests: a board with circular holes in front of a wall and
// above a floor, ray-cast exactly, with Gaussian range noise along the ray.
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"

namespace rgbdt::test {

struct Board {
  Eigen::Isometry3d T_lidar_board = Eigen::Isometry3d::Identity();  // z towards the sensor
  double half_width = 0.6, half_height = 0.6;                         // [m]
  double radius = 0.3;                                                // [m]
  std::vector<Eigen::Vector2d> holes{Eigen::Vector2d::Zero()};        // board frame [m]
  /// Round signs facing the sensor (their plane x = centre.x) that occlude what lies behind.
  struct Sign {
    Eigen::Vector3d center;
    double radius;
  };
  std::vector<Sign> signs;

  Eigen::Vector3d hole_center(std::size_t k) const {
    return T_lidar_board * Eigen::Vector3d(holes[k].x(), holes[k].y(), 0.0);
  }
  Eigen::Vector3d normal() const { return T_lidar_board.linear().col(2); }
};

/// Board facing the sensor at `range` along +x (LIDAR frame x forward, z up), rotated by
/// yaw/pitch [rad] about its own axes.
inline Board board_at(double range, double lateral, double yaw, double pitch, double radius = 0.3) {
  Board b;
  b.radius = radius;
  // Board frame: x right (= -y_lidar), y up (= z_lidar), z towards the sensor (= -x_lidar).
  Eigen::Matrix3d R0;
  R0.col(0) = -Eigen::Vector3d::UnitY();
  R0.col(1) = Eigen::Vector3d::UnitZ();
  R0.col(2) = -Eigen::Vector3d::UnitX();
  const Eigen::Matrix3d R = R0 * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()).toRotationMatrix();
  b.T_lidar_board.linear() = R;
  b.T_lidar_board.translation() = Eigen::Vector3d(range, lateral, 0.1);
  return b;
}

/// Range of the first surface hit along unit direction d, or -1.
inline double cast(const Board& b, const Eigen::Vector3d& d, double wall_x, double floor_z) {
  double best = -1.0;
  const Eigen::Vector3d n = b.normal();
  const Eigen::Vector3d o = b.T_lidar_board.translation();
  const double den = n.dot(d);
  if (std::abs(den) > 1e-9) {
    const double t = n.dot(o) / den;
    if (t > 0) {
      const Eigen::Vector3d q = b.T_lidar_board.inverse() * (t * d);
      bool on = std::abs(q.x()) <= b.half_width && std::abs(q.y()) <= b.half_height;
      for (const auto& h : b.holes) {
        if ((q.head<2>() - h).norm() < b.radius) on = false;
      }
      if (on) best = t;
    }
  }
  auto consider = [&](double t) {
    if (t > 0 && (best < 0 || t < best)) best = t;
  };
  for (const auto& s : b.signs) {
    if (d.x() <= 1e-9) continue;
    const double t = s.center.x() / d.x();
    if ((t * d - s.center).norm() < s.radius) consider(t);
  }
  if (d.x() > 1e-9) consider(wall_x / d.x());
  if (d.z() < -1e-9) consider(floor_z / d.z());
  return best;
}

/// Nodding 2D LIDAR (the paper's Hokuyo on a tilt motor): scan line = one 2D scan,
/// theta in the scan plane, the plane tilted by phi about the y axis. ring = scan index.
inline cloud::Cloud tilting_scan(const Board& b, double noise_m, unsigned seed,
                                 double theta_step_deg = 0.25, double phi_step_deg = 0.5) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_m);
  cloud::Cloud c;
  const double deg = M_PI / 180.0;
  int ring = 0;
  for (double phi = -30.0; phi <= 30.0; phi += phi_step_deg, ++ring) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(phi * deg, Eigen::Vector3d::UnitY()).toRotationMatrix();
    for (double th = -60.0; th <= 60.0; th += theta_step_deg) {
      const Eigen::Vector3d d = R * Eigen::Vector3d(std::cos(th * deg), std::sin(th * deg), 0.0);
      const double r = cast(b, d, b.T_lidar_board.translation().x() + 1.5, -1.2);
      if (r < 0 || r > 30) continue;
      const Eigen::Vector3d p = (r + noise(rng)) * d;
      cloud::PointXYZIRT pt;
      pt.x = static_cast<float>(p.x());
      pt.y = static_cast<float>(p.y());
      pt.z = static_cast<float>(p.z());
      pt.ring = static_cast<std::uint16_t>(ring);
      c.push_back(pt);
    }
  }
  return c;
}

/// Spinning multi-beam LIDAR: beams at fixed elevations, azimuth step; ring = beam.
inline cloud::Cloud spinning_scan(const Board& b, double noise_m, unsigned seed, int beams = 64,
                                  double fov_deg = 30.0, double az_step_deg = 0.2) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_m);
  cloud::Cloud c;
  const double deg = M_PI / 180.0;
  for (int k = 0; k < beams; ++k) {
    const double el = (-fov_deg / 2 + fov_deg * k / (beams - 1)) * deg;
    for (double az = -60.0; az <= 60.0; az += az_step_deg) {
      const Eigen::Vector3d d(std::cos(el) * std::cos(az * deg), std::cos(el) * std::sin(az * deg), std::sin(el));
      const double r = cast(b, d, b.T_lidar_board.translation().x() + 1.5, -1.2);
      if (r < 0 || r > 30) continue;
      const Eigen::Vector3d p = (r + noise(rng)) * d;
      cloud::PointXYZIRT pt;
      pt.x = static_cast<float>(p.x());
      pt.y = static_cast<float>(p.y());
      pt.z = static_cast<float>(p.z());
      pt.ring = static_cast<std::uint16_t>(k);
      c.push_back(pt);
    }
  }
  return c;
}

/// Non-repetitive pattern (Livox-like): random directions in a cone, no scan lines.
inline cloud::Cloud random_scan(const Board& b, double noise_m, unsigned seed, int n = 120000) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_m);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  cloud::Cloud c;
  const double half = 35.0 * M_PI / 180.0;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d d = Eigen::Vector3d(1.0, std::tan(half * u(rng)), std::tan(half * 0.5 * u(rng))).normalized();
    const double r = cast(b, d, b.T_lidar_board.translation().x() + 1.5, -1.2);
    if (r < 0 || r > 30) continue;
    const Eigen::Vector3d p = (r + noise(rng)) * d;
    cloud::PointXYZIRT pt;
    pt.x = static_cast<float>(p.x());
    pt.y = static_cast<float>(p.y());
    pt.z = static_cast<float>(p.z());
    c.push_back(pt);
  }
  return c;
}

}  // namespace rgbdt::test
