#include "rgbdt/core/tilt_rig.hpp"

#include <fstream>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {

std::string ScannerSpec::validate() const {
  std::ostringstream os;
  if (beams < 2) os << "scanner beams " << beams << " must be at least 2";
  else if (!(aperture_rad > 0) || aperture_rad > 2 * M_PI) os << "scanner aperture " << aperture_rad << " rad must be in (0, 2 pi]";
  else if (!(scan_period_s > 0)) os << "scan_period_s " << scan_period_s << " must be positive";
  else if (steps_per_revolution < beams - 1) os << "steps_per_revolution " << steps_per_revolution << " must be >= beams - 1";
  else if (!(range_min_m >= 0) || !(range_max_m > range_min_m)) os << "range limits [" << range_min_m << ", " << range_max_m << "] m are not increasing";
  return os.str();
}

std::string TiltMotorSpec::validate() const {
  if (!(counts_per_revolution > 0)) {
    return "motor counts_per_revolution " + std::to_string(counts_per_revolution) + " must be positive";
  }
  return {};
}

TiltRig read_tilt_rig(const std::string& path) {
  const YAML::Node root = load_yaml_file(path);
  TiltRig rig;
  if (const YAML::Node s = root["scanner"]) {
    const std::string src = path + " (scanner)";
    if (s["beams"]) rig.scanner.beams = require_int(s, "beams", src);
    if (s["aperture_deg"]) rig.scanner.aperture_rad = require_double(s, "aperture_deg", src) * M_PI / 180.0;
    if (s["scan_period_s"]) rig.scanner.scan_period_s = require_double(s, "scan_period_s", src);
    if (s["steps_per_revolution"]) rig.scanner.steps_per_revolution = require_int(s, "steps_per_revolution", src);
    if (s["range_min_m"]) rig.scanner.range_min_m = require_double(s, "range_min_m", src);
    if (s["range_max_m"]) rig.scanner.range_max_m = require_double(s, "range_max_m", src);
  }
  if (const YAML::Node m = root["motor"]) {
    const std::string src = path + " (motor)";
    if (m["counts_per_revolution"]) rig.motor.counts_per_revolution = require_double(m, "counts_per_revolution", src);
    if (m["zero_count"]) rig.motor.zero_count = require_double(m, "zero_count", src);
  }
  if (const YAML::Node m = root["mount"]) {
    const std::string src = path + " (mount)";
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    Eigen::Vector3d rpy = Eigen::Vector3d::Zero();
    if (m["translation"]) {
      const auto v = require_numbers(m, "translation", src, 3);
      t = {v[0], v[1], v[2]};
    }
    if (m["rotation_rpy_deg"]) {
      const auto v = require_numbers(m, "rotation_rpy_deg", src, 3);
      rpy = Eigen::Vector3d(v[0], v[1], v[2]) * M_PI / 180.0;
    }
    rig.T_axis_scanner = make_transform(rotation_from_rpy(rpy[0], rpy[1], rpy[2]), t);
  }
  for (const std::string& why : {rig.scanner.validate(), rig.motor.validate()}) {
    if (!why.empty()) throw Error(path, why);
  }
  return rig;
}

void write_tilt_rig(const std::string& path, const TiltRig& rig) {
  std::ofstream out(path);
  if (!out) throw Error(path, "cannot open file for writing");
  const auto& s = rig.scanner;
  const Eigen::Vector3d t = rig.T_axis_scanner.translation();
  const Eigen::Vector3d rpy = rotation_to_rpy(rig.T_axis_scanner.linear()) * 180.0 / M_PI;
  out << std::setprecision(17);
  out << "# Tilting-LIDAR rig (see rgbdt/core/tilt_rig.hpp for frames and the raw stream)\n";
  out << "scanner: {beams: " << s.beams << ", aperture_deg: " << s.aperture_rad * 180.0 / M_PI
      << ", scan_period_s: " << s.scan_period_s << ", steps_per_revolution: " << s.steps_per_revolution
      << ", range_min_m: " << s.range_min_m << ", range_max_m: " << s.range_max_m << "}\n";
  out << "motor: {counts_per_revolution: " << rig.motor.counts_per_revolution
      << ", zero_count: " << rig.motor.zero_count << "}\n";
  out << "mount: {translation: [" << t.x() << ", " << t.y() << ", " << t.z() << "], rotation_rpy_deg: ["
      << rpy.x() << ", " << rpy.y() << ", " << rpy.z() << "]}\n";
  if (!out) throw Error(path, "write failed");
}

}  // namespace rgbdt::core
