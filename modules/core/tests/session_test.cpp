#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/test/test_util.hpp"

using namespace rgbdt::core;
using rgbdt::test::expect_error_mentions;
using rgbdt::test::write_text;

namespace {
const char* kCalibration = R"(target: {type: circle_hole, radius: 0.30}
cameras:
  rgb:     {intrinsics: rgb.yaml}
  thermal: {intrinsics: thermal.yaml}
views:
  - cloud: clouds/000.pcd
    images: {rgb: rgb/000.png, thermal: thermal/000.png}
    seeds: {rgb: [640, 480], lidar: [4.0, 0.2, 0.1]}
  - cloud: clouds/001.pcd
    images: {rgb: rgb/001.png}
)";

const char* kMapping = R"(lidar:   {rawlog: lidar.rawlog}
cameras:
  rgb:     {intrinsics: rgb.yaml,     frames: rgb/index.csv}
  thermal: {intrinsics: thermal.yaml, frames: thermal/index.csv,
            radiometry: {type: linear, kelvin_per_count: 0.04, offset_k: 0.0}}
)";
}  // namespace

TEST(Session, ReadsCalibrationSessionWithResolvedPaths) {
  const auto dir = rgbdt::test::temp_dir("calib");
  write_text(dir / "session.yaml", kCalibration);
  const CalibrationSession s = read_calibration_session(dir.string());
  EXPECT_EQ(s.directory, dir.string());
  EXPECT_EQ(s.target.type, "circle_hole");
  EXPECT_DOUBLE_EQ(s.target.radius_m, 0.30);
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_EQ(s.cameras.at("rgb").intrinsics, (dir / "rgb.yaml").string());
  ASSERT_EQ(s.views.size(), 2u);
  EXPECT_EQ(s.views[0].cloud, (dir / "clouds/000.pcd").string());
  EXPECT_EQ(s.views[0].images.at("thermal"), (dir / "thermal/000.png").string());
  ASSERT_TRUE(s.views[0].lidar_seed.has_value());
  EXPECT_TRUE(s.views[0].lidar_seed->isApprox(Eigen::Vector3d(4.0, 0.2, 0.1)));
  EXPECT_TRUE(s.views[0].image_seeds.at("rgb").isApprox(Eigen::Vector2d(640, 480)));
  EXPECT_FALSE(s.views[1].lidar_seed.has_value());
  EXPECT_EQ(s.views[1].images.count("thermal"), 0u);
  // The yaml file itself is accepted as well as its folder.
  EXPECT_EQ(read_calibration_session((dir / "session.yaml").string()).views.size(), 2u);
}

TEST(Session, CalibrationWriteThenReadRoundTrips) {
  const auto dir = rgbdt::test::temp_dir("calib");
  write_text(dir / "in/session.yaml", kCalibration);
  CalibrationSession s = read_calibration_session((dir / "in").string());
  s.target.board_size_m = Eigen::Vector2d(1.2, 0.9);
  s.target.holes_m = {{-0.2, 0.1}, {0.2, 0.1}};
  write_calibration_session((dir / "in/copy.yaml").string(), s);
  // Paths under the folder are written relative: the copy reads back identically.
  std::filesystem::rename(dir / "in/copy.yaml", dir / "in/session.yaml");
  const CalibrationSession r = read_calibration_session((dir / "in").string());
  EXPECT_EQ(r.views.size(), s.views.size());
  EXPECT_EQ(r.views[0].cloud, s.views[0].cloud);
  EXPECT_EQ(r.views[0].images, s.views[0].images);
  EXPECT_TRUE(r.views[0].lidar_seed->isApprox(*s.views[0].lidar_seed));
  EXPECT_EQ(r.cameras.at("thermal").intrinsics, s.cameras.at("thermal").intrinsics);
  ASSERT_TRUE(r.target.board_size_m.has_value());
  EXPECT_TRUE(r.target.board_size_m->isApprox(Eigen::Vector2d(1.2, 0.9)));
  ASSERT_EQ(r.target.holes_m.size(), 2u);
  EXPECT_TRUE(r.target.holes_m[1].isApprox(Eigen::Vector2d(0.2, 0.1)));
}

TEST(Session, ReadsMappingSessionWithRadiometry) {
  const auto dir = rgbdt::test::temp_dir("map");
  write_text(dir / "session.yaml", kMapping);
  const MappingSession s = read_mapping_session(dir.string());
  EXPECT_EQ(s.lidar.rawlog, (dir / "lidar.rawlog").string());
  EXPECT_TRUE(s.lidar.clouds.empty());
  EXPECT_EQ(s.cameras.at("rgb").frames, (dir / "rgb/index.csv").string());
  ASSERT_TRUE(s.cameras.at("thermal").radiometry.has_value());
  EXPECT_EQ(s.cameras.at("thermal").radiometry->type, "linear");
  EXPECT_DOUBLE_EQ(s.cameras.at("thermal").radiometry->parameters.at("kelvin_per_count"), 0.04);
  EXPECT_FALSE(s.cameras.at("rgb").radiometry.has_value());
}

TEST(Session, MappingWriteThenReadRoundTrips) {
  const auto dir = rgbdt::test::temp_dir("map");
  MappingSession s;
  s.directory = dir.string();
  s.lidar.clouds = (dir / "clouds/index.csv").string();
  s.lidar.rig = (dir / "tilt_rig.yaml").string();
  s.cameras["rgb"] = {(dir / "rgb.yaml").string(), (dir / "rgb/index.csv").string(), std::nullopt};
  RadiometrySpec r;
  r.parameters = {{"kelvin_per_count", 0.04}, {"offset_k", 1.5}};
  s.cameras["thermal"] = {(dir / "thermal.yaml").string(), (dir / "thermal/index.csv").string(), r};
  s.trajectory = (dir / "ground_truth/trajectory.csv").string();
  write_mapping_session((dir / "session.yaml").string(), s);
  const MappingSession back = read_mapping_session(dir.string());
  EXPECT_EQ(back.lidar.clouds, s.lidar.clouds);
  EXPECT_EQ(back.lidar.rig, s.lidar.rig);
  EXPECT_EQ(back.cameras.at("thermal").frames, s.cameras.at("thermal").frames);
  EXPECT_DOUBLE_EQ(back.cameras.at("thermal").radiometry->parameters.at("offset_k"), 1.5);
  EXPECT_EQ(back.trajectory, s.trajectory);
}

// imu: {samples, rotation_lidar_imu}: written and read back; the rotation is left out of the
// file when it is the identity, and must be a unit quaternion.
TEST(Session, MappingImuRoundTripsAndItsRotationIsChecked) {
  const auto dir = rgbdt::test::temp_dir("imu");
  MappingSession s;
  s.directory = dir.string();
  s.lidar.clouds = (dir / "clouds/index.csv").string();
  s.imu = ImuStream{(dir / "imu.csv").string()};
  write_mapping_session((dir / "session.yaml").string(), s);
  {
    std::ifstream in(dir / "session.yaml");
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(text.find("rotation_lidar_imu"), std::string::npos) << text;
  }
  MappingSession back = read_mapping_session(dir.string());
  ASSERT_TRUE(back.imu.has_value());
  EXPECT_EQ(back.imu->samples, s.imu->samples);
  EXPECT_TRUE(back.imu->rotation_lidar_imu.isApprox(Eigen::Quaterniond::Identity()));
  s.imu->rotation_lidar_imu = Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5);
  write_mapping_session((dir / "session.yaml").string(), s);
  back = read_mapping_session(dir.string());
  EXPECT_TRUE(back.imu->rotation_lidar_imu.isApprox(s.imu->rotation_lidar_imu, 1e-12));
  EXPECT_FALSE(read_mapping_session(dir.string()).imu->samples.empty());
  const std::vector<std::string> problems = preflight_problems(back);
  EXPECT_TRUE(std::any_of(problems.begin(), problems.end(), [](const std::string& p) {
    return p.find("imu.samples") != std::string::npos;
  })) << "imu.csv does not exist";

  write_text(dir / "session.yaml",
             "lidar: {clouds: c.csv}\nimu: {samples: imu.csv, rotation_lidar_imu: [0, 0, 0, 2]}\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); },
                               {"session.yaml", "imu.rotation_lidar_imu", "unit quaternion"});
  write_text(dir / "session.yaml", "lidar: {clouds: c.csv}\nimu: {rotation_lidar_imu: [0, 0, 0, 1]}\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); }, {"session.yaml", "samples"});
  write_text(dir / "session.yaml", "lidar: {clouds: c.csv}\nimu: imu.csv\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); }, {"session.yaml", "imu"});
}

TEST(Session, MissingSessionFileIsReported) {
  const auto dir = rgbdt::test::temp_dir("none");
  expect_error_mentions<Error>([&] { read_calibration_session(dir.string()); }, {"session.yaml"});
}

TEST(Session, BadInputNamesFileKeyAndExpectation) {
  const auto dir = rgbdt::test::temp_dir("bad");
  auto expect = [&](const std::string& text, std::initializer_list<std::string> parts) {
    write_text(dir / "session.yaml", text);
    expect_error_mentions<Error>([&] { read_calibration_session(dir.string()); }, parts);
  };
  expect("cameras: {rgb: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {rgb: a.png}}]\n",
         {"session.yaml", "target"});
  expect("target: {type: circle_hole, radius: -1}\ncameras: {rgb: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {rgb: a.png}}]\n",
         {"session.yaml", "radius", "positive"});
  expect("target: {type: square, radius: 1}\ncameras: {rgb: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {rgb: a.png}}]\n",
         {"square", "circle_hole"});
  expect("target: {type: circle_hole, radius: 0.3}\ncameras: {rgb: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {ir: a.png}}]\n",
         {"views[0]", "'ir'"});
  expect("target: {type: circle_hole, radius: 0.3}\ncameras: {rgb: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {rgb: a.png}, seeds: {lidar: [1, 2]}}]\n",
         {"views[0].seeds", "lidar", "3 numbers"});
  expect("target: {type: circle_hole, radius: 0.3}\ncameras: {rgb: {intrinsics: a.yaml}}\nviews: []\n",
         {"views", "non-empty"});
  expect("target: {type: circle_hole, radius: 0.3}\ncameras: {rgb: {}}\nviews: [{cloud: a.pcd, images: {rgb: a.png}}]\n",
         {"cameras.rgb", "intrinsics"});
}

TEST(Session, MappingSessionNeedsALidarStream) {
  const auto dir = rgbdt::test::temp_dir("bad");
  write_text(dir / "session.yaml", "lidar: {}\ncameras: {rgb: {intrinsics: a.yaml, frames: f.csv}}\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); }, {"lidar", "rawlog", "clouds"});
  write_text(dir / "session.yaml", "lidar: {rawlog: a.rawlog}\ncameras: {rgb: {intrinsics: a.yaml}}\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); }, {"cameras.rgb", "frames"});
}

// `frames: ""` is a camera that recorded nothing (rgbdt_sim mapping --no-images): kept,
// with an empty frames path, and written back the same way.
TEST(Session, MappingCameraWithEmptyFramesRecordedNothing) {
  const auto dir = rgbdt::test::temp_dir("no_frames");
  write_text(dir / "session.yaml", "lidar: {rawlog: a.rawlog}\ncameras: {rgb: {intrinsics: a.yaml, frames: \"\"}}\n");
  const MappingSession s = read_mapping_session(dir.string());
  ASSERT_EQ(s.cameras.count("rgb"), 1u);
  EXPECT_TRUE(s.cameras.at("rgb").frames.empty());
  write_mapping_session((dir / "copy.yaml").string(), s);
  std::filesystem::rename(dir / "copy.yaml", dir / "session.yaml");
  EXPECT_TRUE(read_mapping_session(dir.string()).cameras.at("rgb").frames.empty());
}

namespace {
const std::string kViews = "views: [{cloud: a.pcd, images: {rgb: a.png}}]\n";
const std::string kRgb = "cameras: {rgb: {intrinsics: a.yaml}}\n";

void expect_calibration_error(const std::string& text, std::initializer_list<std::string> parts) {
  const auto dir = rgbdt::test::temp_dir("bad_target");
  write_text(dir / "session.yaml", text);
  expect_error_mentions<Error>([&] { read_calibration_session(dir.string()); }, parts);
}
}  // namespace

TEST(Session, TargetValuesMustBeFiniteAndPhysical) {
  expect_calibration_error("target: {type: circle_hole, radius: .inf}\n" + kRgb + kViews,
                           {"session.yaml", "target.radius", "'.inf'", "metres"});
  expect_calibration_error("target: {type: circle_hole, radius: 7}\n" + kRgb + kViews,
                           {"session.yaml", "target.radius", "'7'", "(0, 5.0] m"});
  expect_calibration_error("target: {type: circle_hole, radius: 0.1, board_size: [-1.2, 0]}\n" + kRgb + kViews,
                           {"session.yaml", "target.board_size", "-1.2", "(0, 20] m"});
  expect_calibration_error("target: {type: circle_hole, radius: 0.3, board_size: [0.5, 0.5]}\n" + kRgb + kViews,
                           {"session.yaml", "target.board_size", "larger than its holes"});
  expect_calibration_error(
      "target: {type: circle_hole, radius: 0.1, board_size: [1, 1], holes: [[0.45, 0]]}\n" + kRgb + kViews,
      {"session.yaml", "target.board_size", "hole 0 at (0.45, 0)"});
  expect_calibration_error("target: {type: circle_hole, radius: 0.1, holes: [[0, .nan]]}\n" + kRgb + kViews,
                           {"session.yaml", "target.holes[0][1]", "'.nan'"});
}

TEST(Session, CameraNamesMustBeUsableAsFileNames) {
  const std::string target = "target: {type: circle_hole, radius: 0.3}\n";
  expect_calibration_error(target + "cameras: {../x: {intrinsics: a.yaml}}\nviews: [{cloud: a.pcd, images: {}}]\n",
                           {"session.yaml", "cameras", "'../x'", "A-Z a-z 0-9 _ -"});
  const std::string long_name(65, 'c');
  expect_calibration_error(target + "cameras: {" + long_name + ": {intrinsics: a.yaml}}\n" + kViews,
                           {"session.yaml", "1 to 64 characters"});
}

TEST(Session, SeedsMustBeFiniteAndNameSessionCameras) {
  const std::string head = "target: {type: circle_hole, radius: 0.3}\n" + kRgb;
  expect_calibration_error(head + "views: [{cloud: a.pcd, images: {rgb: a.png}, seeds: {rgb: [.nan, 3]}}]\n",
                           {"session.yaml", "views[0].seeds.rgb[0]", "'.nan'"});
  expect_calibration_error(head + "views: [{cloud: a.pcd, images: {rgb: a.png}, seeds: {ir: [1, 3]}}]\n",
                           {"session.yaml", "views[0].seeds.ir", "'ir'", "session's cameras"});
  expect_calibration_error(head + "views: [{cloud: a.pcd, images: {rgb: a.png}, seeds: {lidar: [1e300, 0, 0]}}]\n",
                           {"session.yaml", "views[0].seeds.lidar", "1000 m"});
}

TEST(Session, DuplicateKeysAndYamlTypeErrorsNameKeyAndLine) {
  expect_calibration_error("target: {type: circle_hole, radius: 0.3}\n" + kRgb + kViews + "target: {type: circle_hole, radius: 0.5}\n",
                           {"session.yaml", "'target'", "twice", "lines 1 and 4"});
  expect_calibration_error("target: [1, 2]\n" + kRgb + kViews, {"session.yaml", "'target'", "[1, 2]", "circle_hole"});
  expect_calibration_error("target: {type: circle_hole, radius: 0.3}\ncameras: {rgb: [a.yaml]}\n" + kViews,
                           {"session.yaml", "cameras.rgb", "intrinsics"});
  expect_calibration_error("target: {type: circle_hole, radius: 0.3}\n" + kRgb + "views: [{cloud: {x: 1}, images: {rgb: a.png}}]\n",
                           {"session.yaml", "views[0].cloud", "a mapping", "file path"});
}

TEST(Session, FramesNamingAFolderIsAnError) {
  const auto dir = rgbdt::test::temp_dir("frames_folder");
  std::filesystem::create_directories(dir / "rgb");
  write_text(dir / "session.yaml", "lidar: {rawlog: a.rawlog}\ncameras: {rgb: {intrinsics: a.yaml, frames: rgb}}\n");
  expect_error_mentions<Error>([&] { read_mapping_session(dir.string()); },
                               {"session.yaml", "cameras.rgb.frames", "folder", "CSV time index"});
}

TEST(Session, MappingSessionWithoutCamerasIsALidarOnlyMap) {
  for (const std::string cameras : {"", "cameras: {}\n", "cameras:\n"}) {
    const MappingSession s = parse_mapping_session("lidar: {rawlog: a.rawlog}\n" + cameras, "/tmp/s/session.yaml");
    EXPECT_TRUE(s.cameras.empty());
    EXPECT_EQ(s.lidar.rawlog, "/tmp/s/a.rawlog");
  }
}

TEST(Session, RadiometryValuesMustBeFiniteNumbers) {
  expect_error_mentions<Error>(
      [] {
        parse_mapping_session("lidar: {rawlog: a.rawlog}\ncameras: {thermal: {intrinsics: t.yaml, frames: t.csv, "
                              "radiometry: {type: linear, kelvin_per_count: .inf}}}\n", "/s/session.yaml");
      },
      {"/s/session.yaml", "cameras.thermal.radiometry.kelvin_per_count", "'.inf'", "finite"});
  const MappingSession s = parse_mapping_session(kMapping, "/s/session.yaml");
  EXPECT_EQ(s.cameras.at("thermal").radiometry->source, "/s/session.yaml: cameras.thermal.radiometry");
}

TEST(Session, PreflightListsEveryProblemWithoutQuotingFiles) {
  const auto dir = rgbdt::test::temp_dir("preflight");
  write_text(dir / "session.yaml", kCalibration);
  // rgb.yaml holds a line that must never be printed; thermal.yaml is missing; clouds/000.pcd
  // is empty; the rest is missing.
  write_text(dir / "rgb.yaml", "SECRET-FIRST-LINE\n");
  write_text(dir / "clouds/000.pcd", "");
  const CalibrationSession s = read_calibration_session(dir.string());
  const std::vector<std::string> problems = preflight_problems(s);
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  EXPECT_EQ(problems.size(), 7u) << all;  // rgb.yaml, thermal.yaml, 000.pcd, 001.pcd, three images
  EXPECT_EQ(all.find("SECRET"), std::string::npos) << all;
  EXPECT_NE(all.find((dir / "rgb.yaml").string() + ": expected a YAML mapping"), std::string::npos) << all;
  EXPECT_NE(all.find((dir / "thermal.yaml").string() + ": does not exist (expected a camera_info YAML file, named by cameras.thermal.intrinsics)"),
            std::string::npos) << all;
  EXPECT_NE(all.find((dir / "clouds/000.pcd").string() + ": is empty"), std::string::npos) << all;
  EXPECT_NE(all.find("views[1].images.rgb"), std::string::npos) << all;
}

TEST(Session, MappingPreflightChecksIndexesAndTheirRows) {
  const auto dir = rgbdt::test::temp_dir("preflight_map");
  write_text(dir / "session.yaml", "lidar: {clouds: clouds/index.csv}\ncameras: {rgb: {intrinsics: rgb.yaml, frames: rgb/index.csv}}\n");
  write_text(dir / "clouds/index.csv", "time_s,file\n");
  write_text(dir / "rgb/index.csv", "time_s,file\n0.5,000.png\n");
  const MappingSession s = read_mapping_session(dir.string());
  const std::vector<std::string> problems = preflight_problems(s);
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  ASSERT_EQ(problems.size(), 3u) << all;
  EXPECT_NE(all.find("lists no rows"), std::string::npos) << all;
  EXPECT_NE(all.find((dir / "rgb/000.png").string() + ": does not exist"), std::string::npos) << all;
  EXPECT_NE(all.find((dir / "rgb.yaml").string() + ": does not exist"), std::string::npos) << all;
}
