// The tilting LIDAR against analytic geometry: points on the true surfaces within the
// configured noise, timestamps and encoder samples that follow the motion profile.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/sim/lidar_sim.hpp"
#include "rgbdt/sim/rig.hpp"

namespace rgbdt::sim {
namespace {

constexpr double kWallX = 6.0;

// A wall 6 m ahead and the ground 1.1 m below the tilt axis.
Scene wall_scene(double wall_dropout = 0.0) {
  Scene scene;
  Material wall;
  wall.nir_reflectivity = 0.6;
  wall.lidar_dropout_probability = wall_dropout;
  Material ground;
  ground.nir_reflectivity = 0.3;
  scene.add_plane({kWallX, 0, 0}, Eigen::Vector3d::UnitX(), scene.add_material(wall));
  scene.add_plane({0, 0, -1.1}, Eigen::Vector3d::UnitZ(), scene.add_material(ground));
  return scene;
}

Eigen::Isometry3d identity(double) { return Eigen::Isometry3d::Identity(); }

TiltLidarOptions clean_options() {
  TiltLidarOptions o = RigSpec().lidar;
  o.mixed_pixels = false;
  o.dropouts = false;
  return o;
}

TEST(LidarSim, PointsLieOnTheTrueSurfaceWithTheConfiguredRangeNoise) {
  TiltLidarOptions options = clean_options();
  options.range_sigma_m = 0.02;
  TiltLidarSimulator sim(options, 42);
  const Scene scene = wall_scene();
  const auto scans = sim.scans(scene, 0.0, options.profile.tilt_duration_s, identity);
  // Residual along each beam against the analytic wall, with the beam geometry of
  // core::TiltRig (not the simulator's): r_measured - r_true ~ N(0, sigma).
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (const RawScan& s : scans) {
    for (int i = 0; i < options.rig.scanner.beams; ++i) {
      if (!s.valid[static_cast<size_t>(i)]) continue;
      const double t = s.time_s + options.rig.scanner.beam_time_offset(i);
      const Eigen::Isometry3d T = options.rig.T_lidar_scanner(options.profile.angle_rad(t));
      const double th = options.rig.scanner.beam_angle(i);
      const Eigen::Vector3d d = T.linear() * Eigen::Vector3d(std::cos(th), std::sin(th), 0.0);
      const Eigen::Vector3d o = T.translation();
      const double to_wall = d.x() > 1e-9 ? (kWallX - o.x()) / d.x() : 1e9;
      const double to_ground = d.z() < -1e-9 ? (-1.1 - o.z()) / d.z() : 1e9;
      const double truth = std::min(to_wall, to_ground);
      if (truth > options.rig.scanner.range_max_m - 0.2 || truth < 0.3) continue;
      const double r = s.range_m[static_cast<size_t>(i)] - truth;
      sum += r;
      sum2 += r * r;
      ++n;
    }
  }
  ASSERT_GT(n, 5000);
  const double mean = sum / n, rms = std::sqrt(sum2 / n);
  // With n > 5000 samples the RMS of N(0, sigma) is within ~2 % of sigma (4 standard
  // errors) and the mean within ~0.06 sigma.
  EXPECT_NEAR(rms, options.range_sigma_m, 0.04 * options.range_sigma_m);
  EXPECT_LT(std::abs(mean), 0.06 * options.range_sigma_m);
}

TEST(LidarSim, AssembledCloudMatchesRawScansOnTheWall) {
  TiltLidarOptions options = clean_options();
  options.range_sigma_m = 0.01;
  TiltLidarSimulator sim(options, 1);
  const auto scans = sim.scans(wall_scene(), 0.0, options.profile.tilt_duration_s, identity);
  const cloud::Cloud cloud = assemble_cloud(options, scans);
  ASSERT_GT(cloud.size(), 10000u);
  // Distance of every point to the nearer plane: within 5 sigma (false failure 6e-7 per point).
  int far = 0;
  for (const auto& p : cloud) {
    const double d = std::min(std::abs(p.x - kWallX), std::abs(p.z + 1.1));
    if (d > 5 * options.range_sigma_m) ++far;
  }
  EXPECT_EQ(far, 0);
  // ring = scan index and t = time from the first point: scans start every 25 ms and a
  // scan's beams take 1080/1440 of it.
  const double period = options.rig.scanner.scan_period_s;
  const double sweep = options.rig.scanner.beam_time_offset(options.rig.scanner.beams - 1);
  for (const auto& p : cloud) {
    ASSERT_LT(p.ring, scans.size());
    EXPECT_GE(p.t, p.ring * period - sweep - 1e-5);
    EXPECT_LE(p.t, p.ring * period + sweep + 1e-5);
  }
  EXPECT_EQ(scans.size(), static_cast<size_t>(std::round(options.profile.tilt_duration_s / period)));
}

TEST(LidarSim, TiltProfileSweepsBackAndForthAtTheConfiguredRate) {
  TiltProfile p;  // triangle, -30 .. 30 deg, 0.6 s per tilt
  const double a = p.phi_start_rad, b = p.phi_end_rad;
  EXPECT_NEAR(p.angle_rad(0.0), a, 1e-12);
  EXPECT_NEAR(p.angle_rad(0.3), 0.5 * (a + b), 1e-12);
  EXPECT_NEAR(p.angle_rad(0.6 - 1e-9), b, 1e-6);
  EXPECT_NEAR(p.angle_rad(0.9), 0.5 * (a + b), 1e-12);  // on the way back
  EXPECT_NEAR(p.velocity_rad_s(0.1), (b - a) / 0.6, 1e-12);
  EXPECT_NEAR(p.velocity_rad_s(0.7), -(b - a) / 0.6, 1e-12);
  EXPECT_EQ(p.tilt_index(0.59), 0);
  EXPECT_EQ(p.tilt_index(0.61), 1);
  p.shape = TiltProfile::Shape::kSine;
  EXPECT_NEAR(p.velocity_rad_s(0.0), 0.0, 1e-12);
  EXPECT_NEAR(p.angle_rad(0.3), 0.5 * (a + b), 1e-12);
}

TEST(LidarSim, EncoderSamplesAreQuantisedProfileAnglesAtTheConfiguredRate) {
  TiltLidarOptions options = clean_options();
  options.encoder_rate_hz = 200.0;
  TiltLidarSimulator sim(options, 3);
  const auto samples = sim.encoder_samples(10.0, 12.0);
  ASSERT_EQ(samples.size(), 400u);
  const double half_count = M_PI / options.rig.motor.counts_per_revolution;  // half of one count [rad]
  for (size_t k = 0; k < samples.size(); ++k) {
    EXPECT_NEAR(samples[k].time_s, 10.0 + k / 200.0, 1e-9);
    EXPECT_EQ(samples[k].count, std::round(samples[k].count));
    EXPECT_NEAR(samples[k].angle_rad, options.rig.motor.angle_from_count(samples[k].count), 1e-12);
    EXPECT_LE(std::abs(samples[k].angle_rad - options.profile.angle_rad(samples[k].time_s)), half_count + 1e-12);
  }
}

TEST(LidarSim, EncoderInterpolationReproducesTheAssembledCloud) {
  // What the tilt_lidar assembler does with the raw stream: interpolate the encoder at each
  // beam's time and apply core::TiltRig. It must agree with the simulator's cloud up to the
  // encoder quantisation (half a count, plus the interpolation error at the sweep ends).
  TiltLidarOptions options = clean_options();
  TiltLidarSimulator sim(options, 4);
  const auto scans = sim.scans(wall_scene(), 0.0, options.profile.tilt_duration_s, identity);
  const auto enc = sim.encoder_samples(-0.05, options.profile.tilt_duration_s + 0.05);
  double worst = 0.0;
  for (const RawScan& s : scans) {
    for (int i = 0; i < options.rig.scanner.beams; i += 7) {
      if (!s.valid[static_cast<size_t>(i)]) continue;
      const double t = s.time_s + options.rig.scanner.beam_time_offset(i);
      const auto hi = std::upper_bound(enc.begin(), enc.end(), t,
                                       [](double v, const EncoderSample& e) { return v < e.time_s; });
      ASSERT_TRUE(hi != enc.begin() && hi != enc.end());
      const auto lo = hi - 1;
      const double f = (t - lo->time_s) / (hi->time_s - lo->time_s);
      const double phi = lo->angle_rad + f * (hi->angle_rad - lo->angle_rad);
      const double th = options.rig.scanner.beam_angle(i);
      const double r = s.range_m[static_cast<size_t>(i)];
      const Eigen::Vector3d p = options.rig.T_lidar_scanner(phi) * Eigen::Vector3d(r * std::cos(th), r * std::sin(th), 0);
      const Eigen::Vector3d truth = beam_point_lidar(options, s, i);
      // A rotation error about the tilt axis moves a point by angle * its distance from the
      // axis, which is at most its distance from the origin (on the axis).
      const double err_rad = (p - truth).norm() / std::max(truth.norm(), 0.1);
      worst = std::max(worst, err_rad);
    }
  }
  // Half a count is 0.042 deg; the triangle's reversal lies outside the tilt, so linear
  // interpolation adds nothing else.
  EXPECT_LE(worst, M_PI / options.rig.motor.counts_per_revolution * 1.001);
  EXPECT_GT(worst, 0.0);
}

TEST(LidarSim, MixedPixelsAppearOnlyWhenEnabledAndDropoutsFollowTheMaterial) {
  // A board 4 m ahead in front of the wall: its edges straddle a 2 m depth step.
  auto scene_with_board = [](double dropout) {
    Scene scene = wall_scene(dropout);
    Material white;
    white.nir_reflectivity = 0.8;
    BoardSpec board;
    board.T_world_board.linear() << 0, 0, -1, -1, 0, 0, 0, 1, 0;
    board.T_world_board.translation() = Eigen::Vector3d(4.0, 0, 0);
    board.size_m = {1.0, 1.0};
    board.material = scene.add_material(white);
    scene.add_board(board);
    return scene;
  };
  auto between = [](const cloud::Cloud& c) {
    int n = 0;
    for (const auto& p : c) {
      if (p.x > 4.1 && p.x < kWallX - 0.1 && p.z > -1.0) ++n;
    }
    return n;
  };
  TiltLidarOptions options = clean_options();
  const Scene scene = scene_with_board(0.0);
  TiltLidarSimulator clean(options, 5);
  EXPECT_EQ(between(assemble_cloud(options, clean.scans(scene, 0, options.profile.tilt_duration_s, identity))), 0);
  options.mixed_pixels = true;
  TiltLidarSimulator mixed(options, 5);
  // The 1 m board at 4 m spans 14 deg of tilt, so ~6 of the 2.5-deg-apart scan lines cross
  // it, each at two side edges; the 0.25 deg footprint equals the beam spacing, so about
  // one beam per crossing straddles the edge: expect ~12 mixed points, at least 6.
  EXPECT_GE(between(assemble_cloud(options, mixed.scans(scene, 0, options.profile.tilt_duration_s, identity))), 6);

  // Dropouts: the wall loses 40 % of its returns; the ground none (strong, near).
  options.mixed_pixels = false;
  options.dropouts = true;
  TiltLidarSimulator lossy(options, 6);
  const Scene lossy_scene = wall_scene(0.4);
  const auto scans = lossy.scans(lossy_scene, 0, options.profile.tilt_duration_s, identity);
  int wall_valid = 0, wall_total = 0;
  for (const RawScan& s : scans) {
    for (int i = 0; i < options.rig.scanner.beams; ++i) {
      const double t = s.time_s + options.rig.scanner.beam_time_offset(i);
      const Eigen::Isometry3d T = options.rig.T_lidar_scanner(options.profile.angle_rad(t));
      const double th = options.rig.scanner.beam_angle(i);
      const auto hit = lossy_scene.intersect(T.translation(), T.linear() * Eigen::Vector3d(std::cos(th), std::sin(th), 0));
      if (!hit || hit->primitive != 0 || hit->distance > 15.0) continue;
      ++wall_total;
      wall_valid += s.valid[static_cast<size_t>(i)];
    }
  }
  ASSERT_GT(wall_total, 5000);
  // Binomial: the standard error of the fraction is below 0.007; allow 0.03.
  EXPECT_NEAR(static_cast<double>(wall_valid) / wall_total, 0.6, 0.03);
}

TEST(LidarSim, SameSeedSameScansOtherSeedOtherNoise) {
  const TiltLidarOptions options = RigSpec().lidar;
  const Scene scene = wall_scene(0.2);
  TiltLidarSimulator a(options, 9), b(options, 9), c(options, 10);
  const RawScan sa = a.scan(scene, 1.0, identity), sb = b.scan(scene, 1.0, identity), sc = c.scan(scene, 1.0, identity);
  EXPECT_EQ(sa.range_m, sb.range_m);
  EXPECT_EQ(sa.valid, sb.valid);
  EXPECT_NE(sa.range_m, sc.range_m);
}

TEST(LidarSim, RejectsInvalidOptions) {
  TiltLidarOptions options;
  options.range_sigma_m = -1.0;
  EXPECT_THROW(TiltLidarSimulator(options, 1), std::invalid_argument);
  options = TiltLidarOptions();
  options.profile.tilt_duration_s = 0.0;
  EXPECT_THROW(TiltLidarSimulator(options, 1), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::sim
