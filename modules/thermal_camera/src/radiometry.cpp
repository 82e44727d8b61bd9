#include "rgbdt/thermal_camera/radiometry.hpp"

#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

namespace rgbdt::thermal_camera {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// "<file>: cameras.thermal.radiometry (type linear)" for entries read from a session.
std::string spec_context(const core::RadiometrySpec& spec) {
  if (!spec.source.empty()) return spec.source + " (type " + spec.type + ")";
  return "radiometry {type: " + spec.type + "}";
}

std::string num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// Largest gain a linear map may have: a 16-bit count range then spans at most 65535 K.
constexpr double kMaxKelvinPerCount = 1.0;
constexpr double kMaxOffsetK = 10000.0;

double required(const core::RadiometrySpec& spec, const std::string& key,
                const std::string& expected) {
  const auto it = spec.parameters.find(key);
  if (it == spec.parameters.end()) {
    throw std::invalid_argument(spec_context(spec) + ": missing parameter '" + key +
                                "' (expected " + expected + ")");
  }
  return it->second;
}

double optional(const core::RadiometrySpec& spec, const std::string& key, double fallback) {
  const auto it = spec.parameters.find(key);
  return it == spec.parameters.end() ? fallback : it->second;
}

void reject_unknown(const core::RadiometrySpec& spec, const std::set<std::string>& known) {
  for (const auto& [key, value] : spec.parameters) {
    if (known.count(key) == 0) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      throw std::invalid_argument(spec_context(spec) + ": unknown parameter '" + key +
                                  "' (expected one of " + list + ")");
    }
  }
}

// Eq. (2): signal of a black body at t_k.
double planck_signal(const PlanckRadiometry& p, double t_k) {
  return p.R / (std::exp(p.B / t_k) - p.F) + p.O;
}

}  // namespace

std::string LinearRadiometry::validate() const {
  if (!std::isfinite(kelvin_per_count) || kelvin_per_count <= 0.0 || kelvin_per_count > kMaxKelvinPerCount) {
    return "key 'kelvin_per_count' has value " + num(kelvin_per_count) + ", expected a value in (0, " +
           num(kMaxKelvinPerCount) + "] K/count";
  }
  // T(0) = offset_k is the lowest temperature of the count range (kelvin_per_count > 0).
  if (!std::isfinite(offset_k) || offset_k < 0.0 || offset_k > kMaxOffsetK) {
    return "key 'offset_k' has value " + num(offset_k) + ", expected a value in [0, " + num(kMaxOffsetK) +
           "] K (no count may map to a negative temperature)";
  }
  return {};
}

std::string PlanckRadiometry::validate() const {
  if (!std::isfinite(R) || R <= 0.0) return "R = " + std::to_string(R) + ", expected > 0";
  if (!std::isfinite(B) || B <= 0.0) return "B = " + std::to_string(B) + ", expected > 0";
  if (!std::isfinite(F) || F < 0.0) return "F = " + std::to_string(F) + ", expected >= 0";
  if (!std::isfinite(O)) return "O must be finite";
  if (!std::isfinite(emissivity) || emissivity <= 0.0 || emissivity > 1.0) {
    return "emissivity = " + std::to_string(emissivity) + ", expected in (0, 1]";
  }
  if (!std::isfinite(reflected_k) || reflected_k <= 0.0) {
    return "reflected_k = " + std::to_string(reflected_k) + ", expected > 0 K";
  }
  // exp(B / T) - F must stay positive for the reflected signal to exist.
  if (std::exp(B / reflected_k) - F <= 0.0) {
    return "reflected_k = " + std::to_string(reflected_k) + " K is outside the Planck curve " +
           "(exp(B / T) <= F)";
  }
  return {};
}

Radiometry::Radiometry(const LinearRadiometry& linear) : type_(Type::kLinear), linear_(linear) {
  if (const auto why = linear.validate(); !why.empty()) {
    throw std::invalid_argument("linear radiometry: " + why);
  }
}

Radiometry::Radiometry(const PlanckRadiometry& planck) : type_(Type::kPlanck), planck_(planck) {
  if (const auto why = planck.validate(); !why.empty()) {
    throw std::invalid_argument("planck radiometry: " + why);
  }
  reflected_signal_ = planck_signal(planck_, planck_.reflected_k);
  if (!std::isfinite(reflected_signal_)) {
    throw std::invalid_argument("planck radiometry: reflected_k = " + num(planck_.reflected_k) +
                                " K gives a non-finite signal (expected constants of a real camera)");
  }
  // Counts outside the curve carry no temperature (NaN); every other count maps to a finite
  // temperature > 0 K, also as float (the map's lookup table).
  for (int c = 0; c <= 65535; ++c) {
    const double t = kelvin_from_signal(c);
    if (std::isnan(t)) continue;
    if (!(t > 0.0) || !std::isfinite(static_cast<float>(t))) {
      throw std::invalid_argument("planck radiometry: " + std::to_string(c) + " counts give " + num(t) +
                                  " K (expected a finite temperature > 0 K for every 16-bit count)");
    }
  }
}

namespace {
Radiometry from_spec(const core::RadiometrySpec& spec) {
  if (spec.type == "linear") {
    reject_unknown(spec, {"kelvin_per_count", "offset_k"});
    LinearRadiometry l;
    l.kelvin_per_count = required(spec, "kelvin_per_count", "kelvins per count, e.g. 0.04");
    l.offset_k = optional(spec, "offset_k", 0.0);
    if (const auto why = l.validate(); !why.empty()) {
      throw std::invalid_argument(spec_context(spec) + ": " + why);
    }
    return Radiometry(l);
  }
  if (spec.type == "planck") {
    reject_unknown(spec, {"R", "B", "F", "O", "emissivity", "reflected_k"});
    PlanckRadiometry p;
    p.R = required(spec, "R", "the camera's Planck R");
    p.B = required(spec, "B", "the camera's Planck B [K]");
    p.F = optional(spec, "F", 1.0);
    p.O = optional(spec, "O", 0.0);
    p.emissivity = optional(spec, "emissivity", 1.0);
    p.reflected_k = optional(spec, "reflected_k", 293.15);
    if (const auto why = p.validate(); !why.empty()) {
      throw std::invalid_argument(spec_context(spec) + ": " + why);
    }
    return Radiometry(p);
  }
  throw std::invalid_argument("radiometry: unknown type '" + spec.type +
                              "' (expected 'linear' or 'planck')");
}
}  // namespace

Radiometry::Radiometry(const core::RadiometrySpec& spec) : Radiometry(from_spec(spec)) {}

double Radiometry::kelvin_from_signal(double counts) const {
  if (type_ == Type::kLinear) return linear_.kelvin_per_count * counts + linear_.offset_k;
  const PlanckRadiometry& p = planck_;
  // Eq. (3): remove the reflected part, then Eq. (1).
  const double object_signal = (counts - (1.0 - p.emissivity) * reflected_signal_) / p.emissivity;
  const double x = object_signal - p.O;
  if (!(x > 0.0)) return kNaN;
  const double log_arg = p.R / x + p.F;
  if (!(log_arg > 1.0)) return kNaN;  // ln <= 0 would give T <= 0 or infinity
  return p.B / std::log(log_arg);
}

double Radiometry::counts(double kelvin) const {
  if (!std::isfinite(kelvin) || kelvin <= 0.0) {
    throw std::invalid_argument("Radiometry::counts: kelvin = " + std::to_string(kelvin) +
                                ", expected a finite temperature > 0 K");
  }
  if (type_ == Type::kLinear) return (kelvin - linear_.offset_k) / linear_.kelvin_per_count;
  const PlanckRadiometry& p = planck_;
  if (std::exp(p.B / kelvin) - p.F <= 0.0) {
    throw std::invalid_argument("Radiometry::counts: kelvin = " + std::to_string(kelvin) +
                                " is beyond the Planck curve (exp(B / T) <= F)");
  }
  // Eq. (3) forwards.
  return p.emissivity * planck_signal(p, kelvin) + (1.0 - p.emissivity) * reflected_signal_;
}

std::vector<float> Radiometry::lookup_table() const {
  std::vector<float> table(65536);
  for (size_t c = 0; c < table.size(); ++c) {
    table[c] = static_cast<float>(kelvin_from_signal(static_cast<double>(c)));
  }
  return table;
}

std::string Radiometry::describe() const {
  std::ostringstream os;
  if (type_ == Type::kLinear) {
    os << "linear " << linear_.kelvin_per_count << " K/count + " << linear_.offset_k << " K";
  } else {
    os << "planck R=" << planck_.R << " B=" << planck_.B << " F=" << planck_.F << " O=" << planck_.O
       << " emissivity=" << planck_.emissivity << " reflected=" << planck_.reflected_k << " K";
  }
  return os.str();
}

}  // namespace rgbdt::thermal_camera
