#include <gtest/gtest.h>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::core;

TEST(TiltRig, WriteThenReadRoundTrips) {
  TiltRig rig;
  rig.scanner.beams = 721;
  rig.scanner.aperture_rad = 180.0 * M_PI / 180.0;
  rig.motor.counts_per_revolution = 501923;
  rig.motor.zero_count = -12.0;
  rig.T_axis_scanner = make_transform(rotation_from_rpy(0.01, -0.02, 0.005), {0.01, 0.0, 0.06});
  const auto path = rgbdt::test::temp_dir("rig") / "tilt_rig.yaml";
  write_tilt_rig(path.string(), rig);
  const TiltRig back = read_tilt_rig(path.string());
  EXPECT_EQ(back.scanner.beams, 721);
  EXPECT_NEAR(back.scanner.aperture_rad, M_PI, 1e-12);
  EXPECT_DOUBLE_EQ(back.motor.counts_per_revolution, 501923);
  EXPECT_DOUBLE_EQ(back.motor.zero_count, -12.0);
  EXPECT_LT(rotation_error_rad(back.T_axis_scanner, rig.T_axis_scanner), 1e-12);
  EXPECT_LT(translation_error_m(back.T_axis_scanner, rig.T_axis_scanner), 1e-15);
}

TEST(TiltRig, GeometryFollowsTheDocumentedConvention) {
  TiltRig rig;
  rig.T_axis_scanner = make_transform(Eigen::Matrix3d::Identity(), {0, 0, 0.05});
  // A beam straight ahead at 10 m, tilt +10 deg: pitched down (z < 0), and the 5 cm mount
  // offset rotates with the scanner.
  const double phi = 10.0 * M_PI / 180.0;
  const Eigen::Vector3d p = rig.T_lidar_scanner(phi) * Eigen::Vector3d(10, 0, 0);
  EXPECT_NEAR(p.x(), 10 * std::cos(phi) + 0.05 * std::sin(phi), 1e-12);
  EXPECT_NEAR(p.z(), -10 * std::sin(phi) + 0.05 * std::cos(phi), 1e-12);
  EXPECT_NEAR(rig.scanner.beam_angle(0), -135.0 * M_PI / 180.0, 1e-12);
  EXPECT_NEAR(rig.scanner.beam_angle(540), 0.0, 1e-12);
  EXPECT_NEAR(rig.scanner.beam_time_offset(1440), 0.025, 1e-15);
  EXPECT_NEAR(rig.motor.angle_from_count(rig.motor.count_from_angle(0.3)), 0.3, 1e-15);
}

TEST(TiltRig, BadValuesAreNamed) {
  const auto dir = rgbdt::test::temp_dir("bad");
  rgbdt::test::write_text(dir / "r.yaml", "scanner: {beams: 1}\n");
  rgbdt::test::expect_error_mentions<Error>([&] { read_tilt_rig((dir / "r.yaml").string()); },
                                            {"r.yaml", "beams"});
  rgbdt::test::write_text(dir / "r.yaml", "mount: {translation: [0, 0]}\n");
  rgbdt::test::expect_error_mentions<Error>([&] { read_tilt_rig((dir / "r.yaml").string()); },
                                            {"r.yaml", "translation", "3 numbers"});
  rgbdt::test::write_text(dir / "r.yaml", "motor: {counts_per_revolution: 0}\n");
  rgbdt::test::expect_error_mentions<Error>([&] { read_tilt_rig((dir / "r.yaml").string()); },
                                            {"r.yaml", "counts_per_revolution"});
}

TEST(TiltRig, NonFiniteAndUnphysicalValuesAreRefused) {
  auto expect = [](const std::string& text, std::initializer_list<std::string> parts) {
    rgbdt::test::expect_error_mentions<Error>([&] { parse_tilt_rig(text, "r.yaml"); }, parts);
  };
  expect("scanner: {scan_period_s: .inf}\n", {"r.yaml", "scanner.scan_period_s", "'.inf'", "(0, 10] s"});
  expect("scanner: {aperture_deg: .nan}\n", {"r.yaml", "scanner.aperture_deg", "'.nan'"});
  expect("scanner: {range_max_m: 1e300}\n", {"r.yaml", "scanner.range_max_m", "1000"});
  expect("scanner: {beams: 0x439}\n", {"r.yaml", "scanner.beams", "'0x439'"});
  expect("motor: {zero_count: .nan}\n", {"r.yaml", "motor.zero_count", "'.nan'"});
  expect("mount: {translation: [0, 0, .inf]}\n", {"r.yaml", "mount.translation[2]", "'.inf'"});
  expect("mount: {rotation_rpy_deg: [0, 1e308, 0]}\n", {"r.yaml", "mount.rotation_rpy_deg", "degrees"});
  expect("scanner: [1, 2]\n", {"r.yaml", "scanner", "[1, 2]"});
  expect("motor: {zero_count: 1}\nmotor: {zero_count: 2}\n", {"r.yaml", "'motor'", "twice"});
}
