#pragma once
/// \file
/// Thermal camera counts -> scene temperature.
///
/// Two models, selected by core::RadiometrySpec::type:
///   - `linear` (FLIR TLinear): T = kelvin_per_count * counts + offset_k. A Tau2 in TLinear
///     mode outputs 0.04 K per count (high-resolution, "high gain") or 0.4 K per count
///     (low resolution), offset 0.
///   - `planck` (raw, non-TLinear cores): the radiometric calibration constants R, B, F, O
///     of the camera give the object temperature from the (object) signal S:
///         T = B / ln(R / (S - O) + F)                                  (1)
///     and the inverse S(T) = R / (exp(B / T) - F) + O.                   (2)
///     Emissivity e and reflected apparent temperature T_refl are corrected in signal
///     space, where the measured signal is linear in radiance:
///         S = e * S_obj + (1 - e) * S_refl,  S_refl = S(T_refl)            (3)
///     so S_obj = (S - (1 - e) * S_refl) / e before (1). Atmospheric transmission is taken
///     as 1 (short range, as on the paper's rig).
///
/// YAML (session.yaml, cameras.<name>.radiometry):
///   {type: linear, kelvin_per_count: 0.04, offset_k: 0.0}
///   {type: planck, R: 366545, B: 1428, F: 1, O: -342, emissivity: 0.95, reflected_k: 293.15}
/// emissivity defaults to 1 and reflected_k to 293.15 K when absent.
///
/// Ranges: kelvin_per_count in (0, 1] K/count and offset_k in [0, 10000] K, so that every
/// 16-bit count maps to a finite temperature >= 0 K (0 counts may map to 0 K, the TLinear
/// default); a Planck map gives every count either no temperature (NaN, outside the curve)
/// or a finite one > 0 K. Errors from a session's entry name its file and key path
/// (core::RadiometrySpec::source), the parameter and its value.
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/core/session.hpp"

namespace rgbdt::thermal_camera {

/// Parameters of the linear (TLinear) model.
struct LinearRadiometry {
  double kelvin_per_count = 0.04;  ///< [K/count]; Tau2 TLinear: 0.04 (high res) or 0.4 (low res)
  double offset_k = 0.0;           ///< [K] temperature at 0 counts
  std::string validate() const;    ///< empty when valid, else the reason
};

/// Parameters of the Planck model, Eqs. (1)-(3) above.
struct PlanckRadiometry {
  double R = 0.0;               ///< Planck R (R1 / R2 in FLIR metadata) [counts]
  double B = 0.0;               ///< Planck B [K]
  double F = 1.0;               ///< Planck F [-]
  double O = 0.0;               ///< Planck O, signal offset [counts]
  double emissivity = 1.0;      ///< object emissivity, (0, 1]
  double reflected_k = 293.15;  ///< apparent reflected temperature [K]
  std::string validate() const;
};

/// Counts -> kelvin map. Immutable and cheap to copy.
class Radiometry {
 public:
  enum class Type { kLinear, kPlanck };

  explicit Radiometry(const LinearRadiometry& linear);
  explicit Radiometry(const PlanckRadiometry& planck);
  /// Builds from a session's radiometry entry. Throws std::invalid_argument naming the
  /// type or the parameter (missing, unknown or out of range) and what was expected.
  explicit Radiometry(const core::RadiometrySpec& spec);

  Type type() const { return type_; }
  const LinearRadiometry& linear() const { return linear_; }
  const PlanckRadiometry& planck() const { return planck_; }

  /// Scene temperature [K] for a raw pixel value. NaN when the counts lie outside the
  /// domain of the Planck curve (signal at or below the offset O after the emissivity
  /// correction): such pixels carry no temperature.
  double kelvin(uint16_t counts) const { return kelvin_from_signal(counts); }
  /// Same as kelvin() for a fractional signal (e.g. an averaged region).
  double kelvin_from_signal(double counts) const;
  /// Inverse of kelvin(): the (fractional) counts the camera outputs for a scene at
  /// `kelvin`. Throws std::invalid_argument for kelvin <= 0 or non-finite.
  double counts(double kelvin) const;

  /// kelvin(c) for every c in 0..65535, as float (the map rgbdt_map takes). NaN entries
  /// mark counts without a temperature (see kelvin()).
  std::vector<float> lookup_table() const;

  /// One-line description, e.g. "linear 0.04 K/count + 0 K".
  std::string describe() const;

 private:
  Type type_;
  LinearRadiometry linear_;
  PlanckRadiometry planck_;
  double reflected_signal_ = 0.0;  ///< S(T_refl), Eq. (3)
};

}  // namespace rgbdt::thermal_camera
