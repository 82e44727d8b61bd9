#pragma once
// The covariance consistency study of the bench calib_consistency: simulated
// calibration sessions (rgbdt::sim) run through the detectors (rgbdt::calib_targets) and
// align_edges as rgbdt_calibrate runs them, and each solution's true 6-DoF error scored
// against its reported covariance (NEES, inside the 95 % ellipsoid).
//
// The LIDAR is an axis of the study (LidarKind): the tilting 2D LIDAR with its ring field,
// the same clouds with the ring field ignored (the detector recovers the scan lines or
// uses the board's occupancy), a spinning 16-ring LIDAR and a dense cloud without rings.
// A further kind is an enumerator, an entry in kAllLidarKinds and one in sim_lidar().
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/cloud/pcd_io.hpp"
#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/extrinsics/covariance.hpp"
#include "rgbdt/extrinsics/edge_alignment.hpp"
#include "rgbdt/extrinsics/verdict.hpp"
#include "rgbdt/sim/calibration_session.hpp"

namespace rgbdt::extrinsics::study {

enum class LidarKind {
  kTiltRing,     ///< tilting 2D LIDAR, ring field = scan index
  kTiltNoRing,   ///< the same clouds, ring field ignored
  kSpinning16,   ///< spinning 16-ring LIDAR (VLP-16 like), with its ring field
  kDense,        ///< dense non-repetitive cloud without rings (Livox like)
};
inline constexpr LidarKind kAllLidarKinds[] = {LidarKind::kTiltRing, LidarKind::kTiltNoRing, LidarKind::kSpinning16,
                                               LidarKind::kDense};
inline const char* to_string(LidarKind k) {
  switch (k) {
    case LidarKind::kTiltRing: return "tilt-ring";
    case LidarKind::kTiltNoRing: return "tilt-noring";
    case LidarKind::kSpinning16: return "spinning16";
    case LidarKind::kDense: return "dense";
  }
  return "?";
}
/// The simulator's LIDAR for a study kind.
inline sim::LidarKind sim_lidar(LidarKind k) {
  switch (k) {
    case LidarKind::kSpinning16: return sim::LidarKind::kSpinning16;
    case LidarKind::kDense: return sim::LidarKind::kDense;
    default: return sim::LidarKind::kTilt;
  }
}

/// chi-square quantile, 6 degrees of freedom, 0.95: the 95 % ellipsoid is NEES <= this.
inline constexpr double kChi2_6_95 = 12.591587243743977;

struct Case {
  std::uint64_t seed = 1;
  int views = 1;
  int holes = 1;
  double noise_scale = 1.0;  ///< x the rig's 1 cm LIDAR range noise
  LidarKind kind = LidarKind::kTiltRing;
};

struct CaseResult {
  Case c;
  bool ok = false;
  std::string reason;  ///< why the case did not produce a scored solution
  int views_used = 0;
  core::Vector6d error = core::Vector6d::Zero();  ///< to_vector6(estimate) - the truth in its chart
  double nees = 0.0, nees_jacobian = 0.0;
  double err_rot_deg = 0.0, err_trans_cm = 0.0;      ///< |error| rotation, translation
  double sigma_rot_deg = 0.0, sigma_trans_cm = 0.0;  ///< sqrt(trace) of the blocks (total)
  double sigma_rot_jac_deg = 0.0, sigma_trans_jac_cm = 0.0;
  bool jackknife_used = false;
  bool resampled_used = false;  ///< 1-2 views: re-solves on perturbed LIDAR circles
  /// judge_calibration's level ("PASS", "WARN", "FAIL") and its first FAIL reason, else its
  /// first WARN reason.
  std::string verdict;
  std::string verdict_reason;
  double seconds = 0.0;
};

/// n cases cycling through 1-10 views, 1- and 4-hole boards (4 for a single view), noise x0.5-2 and the LIDAR
/// kinds, each with its own seed (first_seed, first_seed + 1, ...).
inline std::vector<Case> make_cases(int n, std::uint64_t first_seed) {
  const int views[] = {1, 2, 3, 5, 7, 10, 4, 6, 8, 9};
  const double noise[] = {0.5, 1.0, 1.5, 2.0, 0.75, 1.25};
  std::vector<Case> cases;
  const int kinds = static_cast<int>(std::size(kAllLidarKinds));
  for (int i = 0; i < n; ++i) {
    Case c;
    c.seed = first_seed + static_cast<std::uint64_t>(i);
    c.views = views[i % 10];
    // One view of a one-hole board leaves the rotation about the hole's axis unobservable:
    // one view always gets the 4-hole board.
    c.holes = c.views == 1 || (i / 2) % 2 == 1 ? 4 : 1;
    c.noise_scale = noise[i % 6];
    c.kind = kAllLidarKinds[(i / 4) % kinds];
    cases.push_back(c);
  }
  return cases;
}

namespace detail {

/// One view as rgbdt_calibrate builds it (all circles against all image edges; per-hole
/// centres for the closed-form guess when both detectors found every hole), plus the LIDAR
/// uncertainty of each hole from its detection.
inline TargetView target_view(const calib_targets::LidarTargetDetection& lidar,
                              const calib_targets::ImageTargetDetection& image,
                              const core::TargetSpec& target, const cv::Size& size,
                              const std::string& name, std::vector<LidarHoleSigma>* sigma) {
  TargetView v;
  v.name = name;
  v.radius_m = target.radius_m;
  v.image_width = size.width;
  v.image_height = size.height;
  for (const auto& h : lidar.holes) {
    v.lidar_circle_points.insert(v.lidar_circle_points.end(), h.circle_points.begin(), h.circle_points.end());
    sigma->push_back(lidar_hole_sigma(h.edge_points, lidar.board_points, h.center, h.normal, target.radius_m,
                                      h.edge_bias_m, lidar.point_spacing_m));
  }
  for (const auto& h : image.holes)
    v.image_edge_points_px.insert(v.image_edge_points_px.end(), h.edge_points_px.begin(), h.edge_points_px.end());
  if (lidar.holes.size() == image.holes.size()) {
    for (std::size_t k = 0; k < lidar.holes.size(); ++k) {
      v.lidar_centers.push_back(lidar.holes[k].center);
      v.lidar_normals.push_back(lidar.holes[k].normal);
      v.image_ellipses.push_back(image.holes[k].ellipse);
    }
  }
  return v;
}

inline double rot_deg(const core::Vector6d& e) { return e.head<3>().norm() * 180.0 / M_PI; }
inline double trans_cm(const core::Vector6d& e) { return e.tail<3>().norm() * 100.0; }

}  // namespace detail

/// A case's RGB views as rgbdt_calibrate builds them, its camera and the true T_rgb_lidar.
struct CaseViews {
  std::vector<TargetView> views;
  core::PinholeCamera camera;
  Eigen::Isometry3d truth;
};

/// The case's views from its session simulated under tmp_dir/case_<seed> (removed
/// afterwards); sets the options' per-view hole sigmas from the detections.
inline CaseViews case_views(const Case& c, const std::filesystem::path& tmp_dir, EdgeAlignmentOptions* options) {
  namespace fs = std::filesystem;
  const fs::path dir = tmp_dir / ("case_" + std::to_string(c.seed));
  fs::remove_all(dir);
  sim::CalibrationSessionOptions opt;
  opt.views = c.views;
  opt.seed = c.seed;
  opt.noise_scale = c.noise_scale;
  opt.holes = c.holes;
  opt.lidar = sim_lidar(c.kind);
  sim::write_calibration_session(dir.string(), opt);
  const core::CalibrationSession session = core::read_calibration_session(dir.string());
  const core::PinholeCamera camera(core::read_camera_info(session.cameras.at("rgb").intrinsics));
  std::vector<TargetView> views;
  options->covariance_model.per_view.clear();
  for (std::size_t i = 0; i < session.views.size(); ++i) {
    const auto& sv = session.views[i];
    const cloud::LoadedCloud loaded = cloud::load_pcd(sv.cloud);
    const bool has_ring = c.kind != LidarKind::kTiltNoRing && loaded.has_ring;
    const auto lidar = calib_targets::detect_target_in_cloud(*loaded.cloud, has_ring, session.target);
    const cv::Mat image = cv::imread(sv.images.at("rgb"), cv::IMREAD_UNCHANGED);
    const auto det = calib_targets::detect_target_in_image(image, session.target, camera);
    if (!lidar.ok || !det.ok) continue;
    std::vector<LidarHoleSigma> sigma;
    views.push_back(detail::target_view(lidar, det, session.target, image.size(), "view " + std::to_string(i), &sigma));
    options->covariance_model.per_view.push_back(std::move(sigma));
  }
  fs::remove_all(dir);
  return {std::move(views), camera, opt.rig.T_rgb_lidar};
}

/// Simulates the case's session under tmp_dir/case_<seed>, calibrates its RGB camera and
/// scores the result. The session directory is removed afterwards. `covariance` holds the
/// covariance model's switches (its per-view sigmas come from the detections).
inline CaseResult run_case(const Case& c, const std::filesystem::path& tmp_dir,
                           const CovarianceOptions& covariance = {}) {
  const auto start = std::chrono::steady_clock::now();
  CaseResult out;
  out.c = c;
  EdgeAlignmentOptions options;
  options.covariance_model = covariance;
  const CaseViews cv = case_views(c, tmp_dir, &options);
  const std::vector<TargetView>& views = cv.views;
  const core::PinholeCamera& camera = cv.camera;
  const Eigen::Isometry3d& truth = cv.truth;
  if (views.empty()) {
    out.reason = "no view with the target found in both the cloud and the image";
    return out;
  }
  try {
    const EdgeAlignmentResult r = align_edges(views, camera, options);
    out.views_used = static_cast<int>(views.size() - r.outlier_views().size());
    if (!r.covariance_valid) {
      out.reason = "covariance not valid: " + r.message;
      return out;
    }
    const core::Vector6d estimate = core::to_vector6(r.T_camera_lidar);  // the covariance's chart
    out.error = estimate - core::to_vector6_near(truth, estimate);
    out.nees = nees(out.error, r.covariance);
    out.nees_jacobian = nees(out.error, r.covariance_terms.jacobian);
    out.err_rot_deg = detail::rot_deg(out.error);
    out.err_trans_cm = detail::trans_cm(out.error);
    out.sigma_rot_deg = std::sqrt(r.covariance.topLeftCorner<3, 3>().trace()) * 180.0 / M_PI;
    out.sigma_trans_cm = std::sqrt(r.covariance.bottomRightCorner<3, 3>().trace()) * 100.0;
    const core::Matrix6d& J = r.covariance_terms.jacobian;
    out.sigma_rot_jac_deg = std::sqrt(J.topLeftCorner<3, 3>().trace()) * 180.0 / M_PI;
    out.sigma_trans_jac_cm = std::sqrt(J.bottomRightCorner<3, 3>().trace()) * 100.0;
    out.jackknife_used = r.covariance_terms.jackknife_used;
    out.resampled_used = r.covariance_terms.resampled_used;
    VerdictOptions vo;
    vo.alignment = options;
    const CalibrationVerdict v = judge_calibration(views, camera, r, vo);
    out.verdict = to_string(v.level);
    for (const auto& reason : v.reasons)
      if (reason.level == VerdictLevel::kFail) {
        out.verdict_reason = reason.text;
        break;
      }
    for (const auto& reason : v.reasons)
      if (out.verdict_reason.empty() && reason.level == VerdictLevel::kWarn) out.verdict_reason = reason.text;
    out.ok = true;
  } catch (const std::exception& e) {
    out.reason = std::string("align_edges: ") + e.what();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

/// chi-square quantile, 6 degrees of freedom, 0.999: a delivered estimate beyond it is wrong
/// by more than its covariance allows (silently wrong).
inline constexpr double kChi2_6_999 = 22.457744484825326;

/// The coverage and NEES are over the delivered cases (verdict PASS or WARN: what a user
/// gets as extrinsics_<camera>.yaml); a FAILed case is written as .rejected.yaml only.
struct Summary {
  int cases = 0;
  int cases_scored_total = 0;  ///< cases with a solution (delivered + failed)
  int scored = 0;              ///< delivered cases, the ones the statistics below are over
  int failed = 0;              ///< solved cases the verdict FAILed
  int silently_wrong = 0;      ///< delivered with NEES beyond the 99.9 % quantile
  int failed_but_right = 0;    ///< FAILed although inside the 95 % ellipsoid
  double inside95 = 0.0, inside95_jacobian = 0.0;  ///< fractions of the scored cases
  double mean_nees = 0.0, mean_nees_jacobian = 0.0;
  double median_sigma_rot_deg = 0.0, median_sigma_trans_cm = 0.0;
  double median_sigma_rot_jac_deg = 0.0, median_sigma_trans_jac_cm = 0.0;
  double median_err_rot_deg = 0.0, median_err_trans_cm = 0.0;
};

inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

inline Summary summarize(const std::vector<CaseResult>& results) {
  Summary s;
  s.cases = static_cast<int>(results.size());
  std::vector<double> sr, st, srj, stj, er, et;
  for (const CaseResult& r : results) {
    if (!r.ok) continue;
    ++s.cases_scored_total;
    if (r.verdict == "FAIL") {
      ++s.failed;
      s.failed_but_right += r.nees <= kChi2_6_95;
      continue;
    }
    s.silently_wrong += r.nees > kChi2_6_999;
    ++s.scored;
    s.inside95 += r.nees <= kChi2_6_95;
    s.inside95_jacobian += r.nees_jacobian <= kChi2_6_95;
    s.mean_nees += r.nees;
    s.mean_nees_jacobian += r.nees_jacobian;
    sr.push_back(r.sigma_rot_deg);
    st.push_back(r.sigma_trans_cm);
    srj.push_back(r.sigma_rot_jac_deg);
    stj.push_back(r.sigma_trans_jac_cm);
    er.push_back(r.err_rot_deg);
    et.push_back(r.err_trans_cm);
  }
  if (s.scored > 0) {
    s.inside95 /= s.scored;
    s.inside95_jacobian /= s.scored;
    s.mean_nees /= s.scored;
    s.mean_nees_jacobian /= s.scored;
  }
  s.median_sigma_rot_deg = median(sr);
  s.median_sigma_trans_cm = median(st);
  s.median_sigma_rot_jac_deg = median(srj);
  s.median_sigma_trans_jac_cm = median(stj);
  s.median_err_rot_deg = median(er);
  s.median_err_trans_cm = median(et);
  return s;
}

}  // namespace rgbdt::extrinsics::study
