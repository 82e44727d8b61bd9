#include "rgbdt/core/tilt_rig.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/output.hpp"
#include "rgbdt/core/transform.hpp"
#include "rgbdt/core/yaml_util.hpp"

namespace rgbdt::core {

std::string ScannerSpec::validate() const {
  std::ostringstream os;
  if (beams < 2) os << "scanner beams " << beams << " must be at least 2";
  else if (!std::isfinite(aperture_rad) || !std::isfinite(scan_period_s) || !std::isfinite(range_min_m) ||
           !std::isfinite(range_max_m)) os << "scanner values must be finite";
  else if (!(aperture_rad > 0) || aperture_rad > 2 * M_PI) os << "scanner aperture " << aperture_rad << " rad must be in (0, 2 pi]";
  else if (!(scan_period_s > 0)) os << "scan_period_s " << scan_period_s << " must be positive";
  else if (steps_per_revolution < beams - 1) os << "steps_per_revolution " << steps_per_revolution << " must be >= beams - 1";
  else if (!(range_min_m >= 0) || !(range_max_m > range_min_m)) os << "range limits [" << range_min_m << ", " << range_max_m << "] m are not increasing";
  return os.str();
}

std::string TiltMotorSpec::validate() const {
  if (!(counts_per_revolution > 0) || !std::isfinite(counts_per_revolution) || !std::isfinite(zero_count)) {
    return "motor counts_per_revolution " + std::to_string(counts_per_revolution) + " must be positive and, with zero_count, finite";
  }
  return {};
}

namespace {

TiltRig parse_rig(const YAML::Node& document, const std::string& source) {
  const YamlField root(document, source);
  TiltRig rig;
  if (const auto s = root.find("scanner")) {
    s->expect_map("{beams, aperture_deg, scan_period_s, steps_per_revolution, range_min_m, range_max_m}");
    auto& sc = rig.scanner;
    if (const auto f = s->find("beams")) sc.beams = static_cast<int>(f->as_integer(2, 100000, "an integer in [2, 100000]"));
    if (const auto f = s->find("aperture_deg")) {
      sc.aperture_rad = f->as_double_in(1e-6, 360.0, "an aperture in (0, 360] degrees") * M_PI / 180.0;
    }
    if (const auto f = s->find("scan_period_s")) sc.scan_period_s = f->as_double_in(1e-6, 10.0, "a scan period in (0, 10] s");
    if (const auto f = s->find("steps_per_revolution")) {
      sc.steps_per_revolution = static_cast<int>(f->as_integer(1, 10000000, "an integer in [1, 10000000]"));
    }
    if (const auto f = s->find("range_min_m")) sc.range_min_m = f->as_double_in(0.0, 1000.0, "a range in [0, 1000] m");
    if (const auto f = s->find("range_max_m")) sc.range_max_m = f->as_double_in(1e-6, 1000.0, "a range in (0, 1000] m");
  }
  if (const auto m = root.find("motor")) {
    m->expect_map("{counts_per_revolution, zero_count}");
    if (const auto f = m->find("counts_per_revolution")) {
      rig.motor.counts_per_revolution = f->as_double_in(1.0, 1e9, "counts per revolution in [1, 1e9]");
    }
    if (const auto f = m->find("zero_count")) rig.motor.zero_count = f->as_double_in(-1e12, 1e12, "a finite count");
  }
  if (const auto m = root.find("mount")) {
    m->expect_map("{translation: [x, y, z], rotation_rpy_deg: [roll, pitch, yaw]}");
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    Eigen::Vector3d rpy = Eigen::Vector3d::Zero();
    if (const auto f = m->find("translation")) {
      const auto v = f->as_numbers(3, "a list of 3 numbers [x, y, z] in metres");
      t = {v[0], v[1], v[2]};
      if (!(t.norm() <= 10.0)) f->fail("expected a mount offset within 10 m of the tilt axis");
    }
    if (const auto f = m->find("rotation_rpy_deg")) {
      const auto v = f->as_numbers(3, "a list of 3 numbers [roll, pitch, yaw] in degrees");
      rpy = Eigen::Vector3d(v[0], v[1], v[2]);
      if (!(rpy.cwiseAbs().maxCoeff() <= 360.0)) f->fail("expected angles within [-360, 360] degrees");
      rpy *= M_PI / 180.0;
    }
    rig.T_axis_scanner = make_transform(rotation_from_rpy(rpy[0], rpy[1], rpy[2]), t);
  }
  for (const std::string& why : {rig.scanner.validate(), rig.motor.validate()}) {
    if (!why.empty()) throw Error(source, why);
  }
  return rig;
}

}  // namespace

TiltRig read_tilt_rig(const std::string& path) { return parse_rig(load_yaml_file(path), path); }

TiltRig parse_tilt_rig(const std::string& yaml_text, const std::string& source) {
  return parse_rig(load_yaml_string(yaml_text, source), source);
}

void write_tilt_rig(const std::string& path, const TiltRig& rig) {
  std::ostringstream out;
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
  write_file_atomic(path, out.str());
}

}  // namespace rgbdt::core
