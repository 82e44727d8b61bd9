// `--config FILE`: values from the file, the command line over them, and every way a file
// can be wrong refused with the file, the key and the line.
#include "app_config.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "rgbdt/test/test_util.hpp"

namespace {

/// An app shaped like the real ones: a positional, numbers with checks, a choice, a flag,
/// a list and a subcommand.
struct Demo {
  CLI::App app{"demo"};
  std::string session;
  double resolution = 0.1;
  std::string icp = "rgicp";
  bool accurate = false;
  std::vector<double> depths{1.0, 2.0};
  int views = 3;
  std::string initial;  // no default: written as `initial: ~`
  CLI::App* sim = nullptr;

  explicit Demo(const std::vector<std::string>& args, const std::string& ini_hint = "")
      : argv_strings(args) {
    argv_strings.insert(argv_strings.begin(), "demo");
    for (const std::string& a : argv_strings) argv.push_back(a.c_str());
    rgbdt::apps::add_config_option(app, static_cast<int>(argv.size()), argv.data(), ini_hint);
    app.add_option("session", session, "session folder");
    app.add_option("--resolution", resolution, "voxel [m]")->check(CLI::PositiveNumber);
    app.add_option("--icp", icp, "backend")->check(CLI::IsMember({"rgicp", "gicp", "icp"}));
    app.add_flag("--accurate", accurate, "slower, tighter");
    app.add_option("--depths", depths, "card distances [m]");
    app.add_option("--initial", initial, "a file, or nothing");
    sim = app.add_subcommand("sim", "a subcommand");
    sim->add_option("--views", views, "views");
  }
  void parse() { app.parse(static_cast<int>(argv.size()), argv.data()); }

  std::vector<std::string> argv_strings;
  std::vector<const char*> argv;
};

std::string parse_error(const std::vector<std::string>& args, const std::string& ini_hint = "") {
  Demo d(args, ini_hint);
  try {
    d.parse();
  } catch (const CLI::ParseError& e) {
    return e.what();
  }
  return {};
}

TEST(AppConfig, FileValuesApplyAndTheCommandLineOverridesThem) {
  const auto file = rgbdt::test::temp_dir("cfg") / "demo.yaml";
  rgbdt::test::write_text(file,
                          "resolution: 0.05   # [m]\nicp: gicp\naccurate: true\ndepths: [3, 4.5]\n"
                          "sim:\n  views: 9\n");
  Demo d({"--config", file.string(), "--icp", "icp", "S", "sim"});
  d.parse();
  EXPECT_DOUBLE_EQ(d.resolution, 0.05);
  EXPECT_EQ(d.icp, "icp");  // the command line wins
  EXPECT_TRUE(d.accurate);
  EXPECT_EQ(d.depths, (std::vector<double>{3.0, 4.5}));
  EXPECT_EQ(d.views, 9);
  EXPECT_EQ(d.session, "S");
}

TEST(AppConfig, UnderscoresStandForHyphens) {
  const auto file = rgbdt::test::temp_dir("cfg") / "demo.yaml";
  rgbdt::test::write_text(file, "resolution: 0.2\n");
  Demo d({"--config=" + file.string()});
  d.parse();
  EXPECT_DOUBLE_EQ(d.resolution, 0.2);
}

TEST(AppConfig, AnUnknownKeyNamesTheFileTheKeyAndTheOptions) {
  const auto file = rgbdt::test::temp_dir("cfg") / "typo.yaml";
  rgbdt::test::write_text(file, "icp: gicp\nresolutoin: 0.05\n");
  const std::string message = parse_error({"--config", file.string()});
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  EXPECT_NE(message.find("resolutoin"), std::string::npos) << message;
  EXPECT_NE(message.find("line 2"), std::string::npos) << message;
  EXPECT_NE(message.find("expected one of: resolution, icp, accurate, depths, initial, sim"),
            std::string::npos)
      << message;
}

TEST(AppConfig, BadValuesDuplicatesAndMissingFilesAreRefused) {
  const auto dir = rgbdt::test::temp_dir("cfg");
  rgbdt::test::write_text(dir / "negative.yaml", "resolution: -1\n");
  EXPECT_NE(parse_error({"--config", (dir / "negative.yaml").string()}).find("-1"),
            std::string::npos);
  rgbdt::test::write_text(dir / "choice.yaml", "icp: ndt\n");
  EXPECT_NE(parse_error({"--config", (dir / "choice.yaml").string()}).find("ndt"),
            std::string::npos);
  rgbdt::test::write_text(dir / "twice.yaml", "icp: gicp\nicp: icp\n");
  const std::string twice = parse_error({"--config", (dir / "twice.yaml").string()});
  EXPECT_NE(twice.find("icp"), std::string::npos) << twice;
  EXPECT_NE(twice.find("twice.yaml"), std::string::npos) << twice;
  rgbdt::test::write_text(dir / "nested.yaml", "resolution: {a: 1}\n");
  EXPECT_NE(parse_error({"--config", (dir / "nested.yaml").string()}).find("resolution"),
            std::string::npos);
  rgbdt::test::write_text(dir / "sub.yaml", "sim:\n  vews: 2\n");
  EXPECT_NE(parse_error({"--config", (dir / "sub.yaml").string()}).find("vews"), std::string::npos);
  EXPECT_NE(parse_error({"--config", (dir / "absent.yaml").string()}).find("absent.yaml"),
            std::string::npos);
}

// An INI file (an MRPT rawlog-grabber section, say) is no YAML of options: the message says
// what the file looks like and, from the app, where an INI goes instead.
TEST(AppConfig, AnIniFileIsRefusedSayingItLooksLikeOneAndWhereItGoes) {
  const auto dir = rgbdt::test::temp_dir("cfg");
  rgbdt::test::write_text(dir / "rig.ini",
                          "# a rig\n[TILT_LIDAR]\nIP_DIR = 192.168.0.10  // [m]: scanner\n"
                          "tilt_min_deg = -20\n");
  const std::string message =
      parse_error({"--config", (dir / "rig.ini").string()}, "the INI goes to `sim --ini FILE`");
  EXPECT_NE(message.find((dir / "rig.ini").string() + " looks like an INI file (line 2: "
                                                      "[TILT_LIDAR])"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("the INI goes to `sim --ini FILE`"), std::string::npos) << message;
  // A section line alone is valid YAML (a list), and still not a mapping of options.
  rgbdt::test::write_text(dir / "section_only.ini", "[TILT_LIDAR]\n");
  const std::string only = parse_error({"--config", (dir / "section_only.ini").string()});
  EXPECT_NE(only.find("looks like an INI file (line 1: [TILT_LIDAR])"), std::string::npos) << only;
  // A broken YAML file without a section line gets no such guess.
  rgbdt::test::write_text(dir / "broken.yaml", "icp: [gicp\n");
  const std::string broken = parse_error({"--config", (dir / "broken.yaml").string()});
  EXPECT_NE(broken.find("broken.yaml"), std::string::npos) << broken;
  EXPECT_EQ(broken.find("INI"), std::string::npos) << broken;
}

TEST(AppConfig, TheEffectiveConfigurationReadsBackAsTheSameValues) {
  const auto dir = rgbdt::test::temp_dir("cfg");
  Demo first(
      {"S", "--resolution", "0.07", "--accurate", "--depths", "5", "6", "sim", "--views", "4"});
  first.parse();
  const std::string yaml = rgbdt::apps::effective_config_yaml(first.app);
  EXPECT_NE(yaml.find("icp: rgicp"), std::string::npos) << yaml;  // a default is named too
  EXPECT_NE(yaml.find("sim:"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("initial: ~"), std::string::npos) << yaml;
  rgbdt::test::write_text(dir / "effective.yaml", yaml);

  Demo second({"--config", (dir / "effective.yaml").string(), "sim"});
  second.parse();
  EXPECT_DOUBLE_EQ(second.resolution, 0.07);
  EXPECT_TRUE(second.accurate);
  EXPECT_EQ(second.depths, (std::vector<double>{5.0, 6.0}));
  EXPECT_EQ(second.views, 4);
  EXPECT_EQ(second.session, "S");
  EXPECT_EQ(second.initial, "");

  const std::string json = rgbdt::apps::effective_config_json(first.app);
  EXPECT_NE(json.find("\"resolution\": \"0.07\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"accurate\": true"), std::string::npos) << json;
  EXPECT_NE(json.find("\"sim\": {"), std::string::npos) << json;
}

}  // namespace
