#include <gtest/gtest.h>

#include <cmath>

#include "rgbdt/thermal_camera/radiometry.hpp"

using rgbdt::core::RadiometrySpec;
using namespace rgbdt::thermal_camera;

namespace {

// Planck constants in the form FLIR publishes them for LWIR cores. B ~ c2 / lambda with
// lambda ~ 10 um (c2 = 14388 um K) gives B ~ 1430 K, F = 1, negative O; R sets the gain.
PlanckRadiometry typical_planck() {
  PlanckRadiometry p;
  p.R = 366545.0;
  p.B = 1428.0;
  p.F = 1.0;
  p.O = -342.0;
  return p;
}

RadiometrySpec spec(const std::string& type, std::map<std::string, double> parameters) {
  RadiometrySpec s;
  s.type = type;
  s.parameters = std::move(parameters);
  return s;
}

}  // namespace

TEST(Radiometry, TLinearHighResolutionIsFourHundredthsOfAKelvinPerCount) {
  const Radiometry r(spec("linear", {{"kelvin_per_count", 0.04}, {"offset_k", 0.0}}));
  EXPECT_EQ(r.type(), Radiometry::Type::kLinear);
  // By definition of TLinear: 7500 counts * 0.04 K = 300 K. Exact up to double rounding.
  EXPECT_NEAR(r.kelvin(7500), 300.0, 1e-9);
  EXPECT_NEAR(r.kelvin(0), 0.0, 1e-12);
  EXPECT_NEAR(r.kelvin(65535), 2621.4, 1e-9);
  EXPECT_NEAR(r.counts(300.0), 7500.0, 1e-9);
}

TEST(Radiometry, TLinearLowResolutionWithOffset) {
  const Radiometry r(spec("linear", {{"kelvin_per_count", 0.4}, {"offset_k", 10.0}}));
  EXPECT_NEAR(r.kelvin(725), 300.0, 1e-9);  // 725 * 0.4 + 10
  EXPECT_NEAR(r.counts(300.0), 725.0, 1e-9);
}

TEST(Radiometry, LinearOffsetDefaultsToZero) {
  const Radiometry r(spec("linear", {{"kelvin_per_count", 0.04}}));
  EXPECT_NEAR(r.kelvin(100), 4.0, 1e-12);
}

TEST(Radiometry, PlanckMatchesHandComputedValue) {
  const Radiometry r(typical_planck());
  // S = 3000: S - O = 3342; R / 3342 = 109.6783; + F = 110.6783; ln = 4.706628;
  // T = 1428 / 4.706628 = 303.4019 K (computed by hand to 7 digits, hence 1e-3 K).
  EXPECT_NEAR(r.kelvin(3000), 303.4019, 1e-3);
  // S = 7000: S - O = 7342; R / 7342 = 49.9245; ln(50.9245) = 3.930316; T = 363.327 K.
  EXPECT_NEAR(r.kelvin(7000), 363.327, 1e-3);
}

TEST(Radiometry, PlanckRoundTripsCountsAndKelvin) {
  const Radiometry r(typical_planck());
  for (double t = 230.0; t <= 420.0; t += 7.5) {
    const double c = r.counts(t);
    // Pure floating-point inversion of Eqs. (1)/(2): relative error ~ 1e-13.
    EXPECT_NEAR(r.kelvin_from_signal(c), t, 1e-9) << "t = " << t;
  }
  for (int c = 100; c < 16384; c += 997) {
    const double t = r.kelvin(static_cast<uint16_t>(c));
    EXPECT_NEAR(r.counts(t), c, 1e-7) << "c = " << c;
  }
}

TEST(Radiometry, EmissivityOneReducesToThePlainCurve) {
  PlanckRadiometry with_reflection = typical_planck();
  with_reflection.emissivity = 1.0;
  with_reflection.reflected_k = 350.0;  // must have no effect when e = 1
  const Radiometry plain(typical_planck()), unity(with_reflection);
  for (int c = 0; c < 65536; c += 1234) {
    const auto cc = static_cast<uint16_t>(c);
    EXPECT_EQ(plain.kelvin(cc), unity.kelvin(cc)) << "c = " << c;
  }
}

TEST(Radiometry, EmissivityCorrectionMatchesHandComputedValue) {
  PlanckRadiometry p = typical_planck();
  p.emissivity = 0.9;
  p.reflected_k = 293.15;
  const Radiometry r(p);
  // S_refl = R / (exp(1428 / 293.15) - 1) + O = 2488.882; S_obj = (7000 - 0.1 * 2488.882) / 0.9
  // = 7501.235; T = 1428 / ln(R / 7843.235 + 1) = 369.408 K.
  EXPECT_NEAR(r.kelvin(7000), 369.408, 1e-3);
  // A grey body hotter than its surroundings reads colder than it is when e is ignored.
  EXPECT_GT(r.kelvin(7000), Radiometry(typical_planck()).kelvin(7000));
  // An object at the reflected temperature reads the same whatever its emissivity.
  EXPECT_NEAR(r.kelvin_from_signal(r.counts(293.15)), 293.15, 1e-9);
  EXPECT_NEAR(r.counts(293.15), Radiometry(typical_planck()).counts(293.15), 1e-9);
}

TEST(Radiometry, CountsBelowTheOffsetHaveNoTemperature) {
  PlanckRadiometry p = typical_planck();
  p.O = 500.0;
  const Radiometry r(p);
  EXPECT_TRUE(std::isnan(r.kelvin(0)));
  EXPECT_TRUE(std::isnan(r.kelvin(500)));
  EXPECT_FALSE(std::isnan(r.kelvin(501)));
}

TEST(Radiometry, LookupTableMatchesKelvinForEveryCount) {
  for (const Radiometry& r :
       {Radiometry(LinearRadiometry{0.04, 0.0}), Radiometry(typical_planck())}) {
    const auto lut = r.lookup_table();
    ASSERT_EQ(lut.size(), 65536u);
    for (size_t c = 0; c < lut.size(); ++c) {
      const double k = r.kelvin(static_cast<uint16_t>(c));
      ASSERT_EQ(static_cast<float>(k), lut[c]) << r.describe() << " c = " << c;
    }
  }
  // Planck table is monotonic increasing wherever defined.
  const auto lut = Radiometry(typical_planck()).lookup_table();
  for (size_t c = 1; c < lut.size(); ++c) ASSERT_GE(lut[c], lut[c - 1]) << c;
}

TEST(Radiometry, BadSpecsNameTheParameter) {
  auto expect_mentions = [](const RadiometrySpec& s, const std::string& part) {
    try {
      Radiometry r(s);
      ADD_FAILURE() << "accepted " << s.type;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_mentions(spec("tlinear", {}), "unknown type 'tlinear'");
  expect_mentions(spec("linear", {}), "missing parameter 'kelvin_per_count'");
  expect_mentions(spec("linear", {{"kelvin_per_count", -0.04}}), "kelvin_per_count");
  expect_mentions(spec("linear", {{"kelvin_per_count", 0.04}, {"gain", 2}}),
                  "unknown parameter 'gain'");
  expect_mentions(spec("planck", {{"B", 1428}}), "missing parameter 'R'");
  expect_mentions(spec("planck", {{"R", 366545}, {"B", 1428}, {"emissivity", 1.5}}), "emissivity");
  EXPECT_THROW(Radiometry(typical_planck()).counts(-1.0), std::invalid_argument);
}

TEST(Radiometry, LinearGainAndOffsetGiveFinitePositiveKelvin) {
  auto expect_mentions = [](const RadiometrySpec& s, std::initializer_list<std::string> parts) {
    try {
      Radiometry r(s);
      ADD_FAILURE() << "accepted " << s.type;
    } catch (const std::invalid_argument& e) {
      for (const auto& part : parts) EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  RadiometrySpec huge = spec("linear", {{"kelvin_per_count", 1e300}});
  huge.source = "/s/session.yaml: cameras.thermal.radiometry";
  expect_mentions(huge, {"/s/session.yaml: cameras.thermal.radiometry", "kelvin_per_count", "1e+300", "(0, 1] K/count"});
  expect_mentions(spec("linear", {{"kelvin_per_count", 0.04}, {"offset_k", -300}}), {"offset_k", "-300", "negative"});
  expect_mentions(spec("linear", {{"kelvin_per_count", 0.04}, {"offset_k", 1e300}}), {"offset_k", "1e+300"});
  // The TLinear default maps 0 counts to 0 K and the whole range to finite temperatures.
  const auto lut = Radiometry(spec("linear", {{"kelvin_per_count", 0.04}, {"offset_k", 0.0}})).lookup_table();
  for (const float t : lut) ASSERT_TRUE(std::isfinite(t) && t >= 0.0f) << t;
}

TEST(Radiometry, PlanckConstantsGivingInfiniteKelvinAreRefused) {
  PlanckRadiometry p = typical_planck();
  p.B = 1e300;  // B / ln(...) overflows float for every count on the curve
  EXPECT_THROW(Radiometry{p}, std::invalid_argument);
}
