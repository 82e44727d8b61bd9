#include "rgbdt/tilt_lidar/assembler.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

#include "stream_fixture.hpp"

namespace rgbdt::tilt_lidar {
namespace {

using test::MotionProfile;

// Error bound for a point at range r. Each encoder sample is within half a count of the
// true angle and linear interpolation between two such samples stays within half a count
// plus the chord error of the sinusoid over 5 ms (A w^2 dt^2 / 8 = 4.3e-5 rad). A tilt error
// moves the point by at most its distance to the tilt axis (r + 0.06 m of mount lever).
// Float storage adds ~1e-6 relative.
double bound_m(const core::TiltRig& rig, double r) {
  const double half_count = M_PI / rig.motor.counts_per_revolution;
  return (r + 0.06) * (half_count + 5e-5) + 1e-5 * r;
}

struct Check {
  double max_excess = -1e9;  // max(error - bound); must stay <= 0
  std::int64_t points = 0;
};

// Compares every point with the ground truth of its beam, identified through the
// spherical record (theta -> beam index) and the point's absolute time.
Check check_tilts(const std::vector<TiltCloud>& tilts, const core::TiltRig& rig, const MotionProfile& m) {
  Check c;
  const double dtheta = rig.scanner.aperture_rad / (rig.scanner.beams - 1);
  for (const auto& tc : tilts) {
    EXPECT_EQ(tc.cloud->size(), tc.spherical.size());
    for (std::size_t k = 0; k < tc.cloud->size(); ++k) {
      const auto& p = tc.cloud->points[k];
      const auto& sp = tc.spherical[k];
      const int beam = static_cast<int>(std::lround((sp.theta_rad + 0.5 * rig.scanner.aperture_rad) / dtheta));
      const double t = tc.start_time_s + p.t;
      const Eigen::Vector3d truth = test::true_point(rig, m, t, beam, sp.r_m);
      const double err = (Eigen::Vector3d(p.x, p.y, p.z) - truth).norm();
      c.max_excess = std::max(c.max_excess, err - bound_m(rig, sp.r_m));
      ++c.points;
    }
  }
  return c;
}

TEST(Assembler, PointsMatchGroundTruthWithinEncoderQuantisation) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  const auto stream = test::make_stream(rig, m, 3.0);
  Assembler a(rig);
  const auto tilts = test::feed(a, stream);
  const Check c = check_tilts(tilts, rig, m);
  EXPECT_LE(c.max_excess, 0.0);
  // Reversals at 0.3, 0.9, 1.5, 2.1, 2.7 s: 4 full tilts between two partial ones.
  ASSERT_EQ(tilts.size(), 6u);
  EXPECT_TRUE(tilts.front().partial);
  EXPECT_TRUE(tilts.back().partial);
  const auto turns = m.reversals(0.0, 3.0);
  for (int k = 1; k <= 4; ++k) {
    const auto& tc = tilts[k];
    EXPECT_FALSE(tc.partial);
    // The turn is located as the midpoint of the encoder plateau at the extreme: within a
    // beam period (~17 us) plus half the plateau's sampling uncertainty (one 5 ms sample).
    EXPECT_NEAR(tc.start_time_s, turns[k - 1], 0.0055);
    EXPECT_NEAR(tc.end_time_s, turns[k], 0.0055);
    EXPECT_EQ(tc.direction, k % 2 == 1 ? -1 : 1);  // falling after the first maximum at 0.3 s
    EXPECT_GE(tc.stats.scans, 24);                 // 600 ms / 25 ms, plus split scans
    EXPECT_LE(tc.stats.scans, 25);
    EXPECT_EQ(tc.stats.dropped_gap, 0);
    EXPECT_EQ(tc.stats.points + tc.stats.invalid, tc.stats.beams);
    EXPECT_EQ(tc.cloud->points.front().t, 0.0f);
    EXPECT_EQ(tc.cloud->points.front().ring, 0);
    EXPECT_EQ(tc.cloud->points.back().ring, tc.stats.scans - 1);
    EXPECT_NEAR(tc.cloud->points.back().t, 0.6, 0.006);
  }
  // Every beam accounted for: scans x beams.
  EXPECT_EQ(a.stats().beams, static_cast<std::int64_t>(stream.scans.size()) * rig.scanner.beams);
  EXPECT_EQ(a.stats().points, c.points);
  EXPECT_EQ(a.stats().reversals, 5);
}

TEST(Assembler, SphericalCoordinatesAreRangeBeamAngleAndTilt) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  const auto stream = test::make_stream(rig, m, 1.0);
  Assembler a(rig);
  const auto tilts = test::feed(a, stream);
  ASSERT_FALSE(tilts.empty());
  const auto& tc = tilts[1];
  for (std::size_t k = 0; k < tc.cloud->size(); k += 97) {
    const auto& sp = tc.spherical[k];
    const double t = tc.start_time_s + tc.cloud->points[k].t;
    EXPECT_NEAR(sp.phi_rad, m.phi(t), M_PI / 4096 + 5e-5);  // half a count + chord error
    const auto& p = tc.cloud->points[k];
    // Rebuild the point from (r, theta, phi) through the rig: exact up to float rounding.
    const Eigen::Vector3d q = rig.T_lidar_scanner(sp.phi_rad) *
                              Eigen::Vector3d(sp.r_m * std::cos(sp.theta_rad), sp.r_m * std::sin(sp.theta_rad), 0);
    EXPECT_NEAR((q - Eigen::Vector3d(p.x, p.y, p.z)).norm(), 0.0, 1e-5);
  }
}

TEST(Assembler, PerScanTiltWouldBeFarOutsideTheBound) {
  // Guards the test itself: the tilt moves ~2 deg during one scan, so using the scan's
  // timestamp for all beams would break the bound by centimetres.
  const auto rig = test::test_rig();
  const MotionProfile m;
  const double move = std::abs(m.phi(0.0 + 0.01875) - m.phi(0.0));
  EXPECT_GT(move * 5.0, 10 * bound_m(rig, 5.0) / 5.0);
}

TEST(Assembler, ReversalInsideAScanSplitsItsBeamsBetweenTwoTilts) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  // Scan at 0.2930 s runs until ~0.3118 s, across the maximum at 0.3 s.
  const auto stream = test::make_stream(rig, m, 1.0, 0.0180);
  Assembler a(rig);
  const auto tilts = test::feed(a, stream);
  ASSERT_GE(tilts.size(), 2u);
  const auto& first = tilts[0];
  const auto& second = tilts[1];
  const double scan_t = 0.0180 + 11 * 0.025;  // 0.293
  EXPECT_GT(first.end_time_s, scan_t);
  EXPECT_LT(second.start_time_s, scan_t + 0.019);
  EXPECT_NEAR(first.end_time_s, 0.3, 0.0055);
  EXPECT_NEAR(second.start_time_s, 0.3, 0.0055);
  // The split scan is the last ring of the first tilt and ring 0 of the second.
  EXPECT_EQ(first.cloud->points.back().ring, first.stats.scans - 1);
  EXPECT_EQ(second.cloud->points.front().ring, 0);
  EXPECT_EQ(first.direction, 1);
  EXPECT_EQ(second.direction, -1);
  EXPECT_LE(check_tilts(tilts, rig, m).max_excess, 0.0);
}

TEST(Assembler, EncoderGapDropsAndCountsTheBeamsInside) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  auto stream = test::make_stream(rig, m, 2.0);
  // Lose the samples in (1.0, 1.1) s: the interval from 1.0 to 1.1 s is a 100 ms gap.
  std::vector<EncoderSample> kept;
  for (const auto& e : stream.encoder) if (!(e.time_s > 1.0 + 1e-9 && e.time_s < 1.1 - 1e-9)) kept.push_back(e);
  stream.encoder = kept;
  std::int64_t expected_gap = 0;
  for (const auto& s : stream.scans)
    for (int i = 0; i < rig.scanner.beams; ++i) {
      const double tb = s.time_s + rig.scanner.beam_time_offset(i);
      if (tb > 1.0 && tb < 1.1 && s.valid[i]) ++expected_gap;
    }
  AssemblerOptions opt;
  opt.max_encoder_gap_s = 0.05;
  Assembler a(rig, opt);
  const auto tilts = test::feed(a, stream);
  EXPECT_EQ(a.stats().dropped_gap, expected_gap);
  EXPECT_GT(expected_gap, 3000);
  EXPECT_LE(check_tilts(tilts, rig, m).max_excess, 0.0);

  // With a limit above the gap the beams are interpolated across it (and are less exact).
  opt.max_encoder_gap_s = 0.2;
  Assembler b(rig, opt);
  test::feed(b, stream);
  EXPECT_EQ(b.stats().dropped_gap, 0);
}

TEST(Assembler, OutOfOrderAndDuplicatedInputGivesTheSameClouds) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  const auto clean = test::make_stream(rig, m, 2.0);
  Assembler ref(rig);
  const auto expected = test::feed(ref, clean);

  auto messy = clean;
  std::mt19937 rng(7);
  // Swap neighbouring encoder samples (late by one sample), duplicate every 10th.
  for (std::size_t k = 1; k + 1 < messy.encoder.size(); k += 3) std::swap(messy.encoder[k], messy.encoder[k + 1]);
  std::vector<EncoderSample> enc;
  for (std::size_t k = 0; k < messy.encoder.size(); ++k) {
    enc.push_back(messy.encoder[k]);
    if (k % 10 == 0) enc.push_back(messy.encoder[k]);
  }
  messy.encoder = enc;
  // Swap scan pairs and duplicate every 7th scan.
  for (std::size_t k = 2; k + 1 < messy.scans.size(); k += 5) std::swap(messy.scans[k], messy.scans[k + 1]);
  std::vector<Scan> scans;
  for (std::size_t k = 0; k < messy.scans.size(); ++k) {
    scans.push_back(messy.scans[k]);
    if (k % 7 == 0) scans.push_back(messy.scans[k]);
  }
  messy.scans = scans;

  Assembler a(rig);
  const auto got = test::feed(a, messy);
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].cloud->size(), expected[k].cloud->size()) << "tilt " << k;
    for (std::size_t i = 0; i < got[k].cloud->size(); i += 13) {
      EXPECT_EQ(got[k].cloud->points[i].x, expected[k].cloud->points[i].x);
      EXPECT_EQ(got[k].cloud->points[i].z, expected[k].cloud->points[i].z);
    }
  }
  EXPECT_GT(a.stats().encoder_duplicate, 30);
  EXPECT_GT(a.stats().encoder_reordered, 50);
  EXPECT_GT(a.stats().scans_duplicate, 5);
  EXPECT_GT(a.stats().scans_reordered, 5);
  EXPECT_EQ(a.stats().encoder_late, 0);
}

TEST(Assembler, CompensatesAClockOffsetBetweenTheStreams) {
  const auto rig = test::test_rig();
  const MotionProfile m;
  auto stream = test::make_stream(rig, m, 2.0);
  for (auto& e : stream.encoder) e.time_s += 100.0;  // encoder clock runs 100 s ahead
  AssemblerOptions opt;
  opt.encoder_time_offset_s = -100.0;
  Assembler a(rig, opt);
  EXPECT_LE(check_tilts(test::feed(a, stream), rig, m).max_excess, 0.0);

  // A 20 ms residual offset puts points off by far more than the quantisation bound.
  opt.encoder_time_offset_s = -100.02;
  Assembler b(rig, opt);
  EXPECT_GT(check_tilts(test::feed(b, stream), rig, m).max_excess, 0.01);
}

TEST(Assembler, LateSamplesBeyondTheReorderWindowAreCountedNotUsed) {
  const auto rig = test::test_rig();
  Assembler a(rig);
  a.add_encoder_sample({0.0, 0.0});
  a.add_encoder_sample({1.0, 0.1});
  a.add_encoder_sample({0.5, 0.05});  // 0.5 s late, window is 0.05 s
  a.add_encoder_sample({1.0, 0.1});   // duplicate
  EXPECT_EQ(a.stats().encoder_late, 1);
  EXPECT_EQ(a.stats().encoder_duplicate, 1);
}

TEST(Assembler, RejectsBadOptionsAndCountsWrongScanSizes) {
  AssemblerOptions bad;
  bad.max_encoder_gap_s = 0;
  EXPECT_NE(bad.validate().find("max_encoder_gap_s"), std::string::npos);
  EXPECT_THROW(Assembler(core::TiltRig{}, bad), std::invalid_argument);
  Assembler a(core::TiltRig{});
  Scan s;
  s.time_s = 1.0;
  s.ranges_m.assign(100, 1.0f);
  EXPECT_TRUE(a.add_scan(s).empty());
  EXPECT_EQ(a.stats().scans_bad_size, 1);
  s.time_s = std::nan("");
  EXPECT_THROW(a.add_scan(s), std::invalid_argument);
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
