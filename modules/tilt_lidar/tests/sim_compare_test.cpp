// The assembler against the simulator (modules/sim): sim's raw stream (lidar.rawlog, the
// tilt_rig.hpp contract) replayed through replay_rawlog, compared point by point with the
// clouds sim assembles from the TRUE tilt angle (ground truth up to the encoder).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <unordered_map>

#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"
#include "rgbdt/sim/mapping_session.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"
#include "rgbdt/test/test_util.hpp"

namespace rgbdt::tilt_lidar {
namespace {

namespace fs = std::filesystem;

// Beam times are scan_time + i * 25 ms / 1440 (17.4 us apart): a 1 us key is unique.
long long key(double t) { return std::llround(t * 1e6); }

TEST(SimCompare, AssembledTiltsMatchSimGroundTruthWithinEncoderQuantisation) {
  const fs::path dir = test::temp_dir("session");
  sim::MappingSessionOptions so;
  so.duration_s = 2.5;
  so.write_images = false;
  sim::write_mapping_session(dir.string(), so);
  const core::TiltRig rig = core::read_tilt_rig((dir / "tilt_rig.yaml").string());

  std::unordered_map<long long, Eigen::Vector3f> truth;
  for (const auto& entry : core::read_time_index((dir / "clouds/index.csv").string())) {
    const auto loaded = cloud::load_pcd(entry.file);
    for (const auto& p : loaded.cloud->points) truth[key(entry.time_s + p.t)] = p.getVector3fMap();
  }
  ASSERT_GT(truth.size(), 50000u);

  Assembler assembler(rig);
  std::vector<TiltCloud> tilts;
  const auto r = replay_rawlog((dir / "lidar.rawlog").string(), assembler,
                               [&](TiltCloud&& t) { tilts.push_back(std::move(t)); });
  ASSERT_FALSE(r.truncated) << r.error;
  ASSERT_GE(tilts.size(), 4u);

  // Tight bound: half an encoder count of tilt error, at the point's distance from the
  // tilt axis (plus the 5 cm mount lever), plus float rounding. Near a reversal of the
  // triangular sweep the chord between the two samples around the apex cuts the corner by
  // up to v * dt / 2 (1.75 rad/s, 10 ms: 8.7 mrad); those points get that allowance.
  const double half_count = M_PI / rig.motor.counts_per_revolution;
  const double sweep_speed = 60.0 * M_PI / 180.0 / 0.6;
  const double encoder_dt = 0.01;
  std::size_t matched = 0, total = 0;
  double worst_tight = 0.0;
  for (const auto& tc : tilts) {
    for (std::size_t k = 0; k < tc.cloud->size(); ++k) {
      const auto& p = tc.cloud->points[k];
      const double t = tc.start_time_s + p.t;
      ++total;
      const auto it = truth.find(key(t));
      if (it == truth.end()) continue;  // sim drops the last, incomplete tilt
      ++matched;
      const double r_m = tc.spherical[k].r_m + 0.05;
      const double err = (p.getVector3fMap() - it->second).norm();
      // Distance in time to the nearest turn (tilts start at 100 s, 0.6 s each).
      const double phase = std::fmod(t - 100.0, 0.6);
      const double to_turn = std::min(phase, 0.6 - phase);
      const bool near_turn = to_turn < encoder_dt;
      const double bound = r_m * (half_count + (near_turn ? sweep_speed * encoder_dt / 2 : 0.0)) + 1e-5 * r_m;
      EXPECT_LE(err, bound) << "point at t=" << t << " r=" << r_m;
      if (!near_turn) worst_tight = std::max(worst_tight, err / r_m);
    }
  }
  EXPECT_GT(matched, total * 9 / 10);
  EXPECT_LE(worst_tight, half_count + 1e-5);
  // Every full sim tilt reappears: tilt boundaries at the reversals (every 0.6 s).
  for (const auto& tc : tilts) {
    if (tc.partial) continue;
    EXPECT_NEAR(std::fmod(tc.start_time_s - 100.0 + 0.3, 0.6), 0.3, 0.011);  // one encoder period
  }
}

}  // namespace
}  // namespace rgbdt::tilt_lidar
