// The covariance consistency study of issue #29 item 4: simulated calibration sessions
// (1-10 views, 1- and 4-hole boards, LIDAR range noise 0.5-2 cm, beam footprint and mixed
// pixels on, ring and no-ring clouds), each calibrated as rgbdt_calibrate does it, and the
// true 6-DoF error of each scored against the reported covariance.
//
//   cmake --build build --target calib_consistency && build/bin/calib_consistency [--cases 60]
//
// Each case is judged (PASS/WARN/FAIL) as the app judges it; the coverage is over the
// delivered (not FAILed) cases, and a delivered case beyond its 99.9 % ellipsoid counts as
// silently wrong. Prints one line per case and the summary: the fraction of delivered cases
// whose error lies inside the 95 % ellipsoid (target 90-99 %), the mean NEES (target 3-9; chi-square with 6 degrees
// of freedom has mean 6), the same for the Jacobian-only covariance, and the median
// reported 1-sigma against the median true error. Exits 1 when a target is missed.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "consistency_study.hpp"
#include "rgbdt/core/log.hpp"

namespace study = rgbdt::extrinsics::study;

int main(int argc, char** argv) {
  CLI::App app{"calib_consistency: does the extrinsics covariance contain the truth as often as it says?"};
  int cases = 60;
  std::uint64_t first_seed = 1;
  std::string tmp = (std::filesystem::temp_directory_path() / "rgbdt_calib_consistency").string();
  app.add_option("--cases", cases, "number of simulated sessions (>= 50 for the issue's study)")->check(CLI::Range(1, 10000));
  app.add_option("--first-seed", first_seed, "seed of the first session");
  app.add_option("--tmp", tmp, "directory for the sessions (each removed after use)");
  std::uint64_t only = 0;
  app.add_option("--only", only,
                 "run only the case with this seed (of the --cases from --first-seed), e.g. to look at one "
                 "outlier again");
  bool jackknife_polish = false;
  app.add_flag("--jackknife-polish", jackknife_polish,
               "leave-one-view-out solutions as LM polishes to convergence instead of one Gauss-Newton step "
               "(CovarianceOptions::jackknife_one_step = false), to compare the two");
  CLI11_PARSE(app, argc, argv);
  rgbdt::extrinsics::CovarianceOptions covariance;
  covariance.jackknife_one_step = !jackknife_polish;
  rgbdt::core::set_log_level(rgbdt::core::LogLevel::kWarning);

  std::printf("%4s %5s %5s %5s %-11s %4s | %8s %8s | %7s %7s %7s %7s | %5s %5s %s\n", "seed", "views", "holes",
              "noise", "lidar", "used", "NEES", "NEES_J", "err_deg", "sig_deg", "err_cm", "sig_cm", "extra", "time",
              "verdict");
  std::vector<study::CaseResult> results;
  for (const study::Case& c : study::make_cases(cases, first_seed)) {
    if (only != 0 && c.seed != only) continue;
    const study::CaseResult r = study::run_case(c, tmp, covariance);
    results.push_back(r);
    if (!r.ok) {
      std::printf("%4lu %5d %5d %5.2f %-11s  -- not scored: %s\n", static_cast<unsigned long>(c.seed), c.views, c.holes,
                  c.noise_scale, study::to_string(c.kind), r.reason.c_str());
      continue;
    }
    std::printf("%4lu %5d %5d %5.2f %-11s %4d | %8.2f %8.1f | %7.3f %7.3f %7.3f %7.3f | %5s %4.1fs %s%s%s\n",
                static_cast<unsigned long>(c.seed), c.views, c.holes, c.noise_scale, study::to_string(c.kind),
                r.views_used, r.nees, r.nees_jacobian, r.err_rot_deg, r.sigma_rot_deg, r.err_trans_cm, r.sigma_trans_cm,
                r.jackknife_used ? "jk" : r.resampled_used ? "rs" : "no", r.seconds, r.verdict.c_str(), r.verdict_reason.empty() ? "" : ": ",
                r.verdict_reason.substr(0, only != 0 ? std::string::npos : 90).c_str());
    std::fflush(stdout);
  }
  const study::Summary s = study::summarize(results);
  std::printf("\n%d cases, %d solved, %d FAILed by the verdict (%d of them inside their 95 %% ellipsoid), "
              "%d delivered (PASS/WARN) and scored below\n",
              s.cases, s.cases_scored_total, s.failed, s.failed_but_right, s.scored);
  std::printf("delivered outside the 99.9 %% ellipsoid (silently wrong): %d\n", s.silently_wrong);
  std::printf("%-22s %12s %10s %14s %14s\n", "covariance", "inside 95%", "mean NEES", "median sig deg", "median sig cm");
  std::printf("%-22s %11.1f%% %10.2f %14.4f %14.4f\n", "total (reported)", 100.0 * s.inside95, s.mean_nees,
              s.median_sigma_rot_deg, s.median_sigma_trans_cm);
  std::printf("%-22s %11.1f%% %10.2f %14.4f %14.4f\n", "jacobian only", 100.0 * s.inside95_jacobian,
              s.mean_nees_jacobian, s.median_sigma_rot_jac_deg, s.median_sigma_trans_jac_cm);
  std::printf("median true error: %.4f deg, %.4f cm\n", s.median_err_rot_deg, s.median_err_trans_cm);
  const bool coverage_ok = s.inside95 >= 0.90 && s.inside95 <= 0.99;
  const bool nees_ok = s.mean_nees >= 3.0 && s.mean_nees <= 9.0;
  const bool scored_ok = s.cases_scored_total == s.cases;
  const bool honest_ok = s.silently_wrong == 0;
  std::printf("coverage in [90, 99] %%: %s; mean NEES in [3, 9]: %s; every case solved: %s; none silently wrong: %s\n",
              coverage_ok ? "PASS" : "FAIL", nees_ok ? "PASS" : "FAIL", scored_ok ? "PASS" : "FAIL",
              honest_ok ? "PASS" : "FAIL");
  return coverage_ok && nees_ok && scored_ok && honest_ok ? 0 : 1;
}
