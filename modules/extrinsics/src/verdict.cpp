#include "rgbdt/extrinsics/verdict.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/transform.hpp"
#include "rgbdt/extrinsics/hole_pairing.hpp"

namespace rgbdt::extrinsics {

namespace {

std::string fmt(const char* format, double a, double b = 0.0, double c = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, format, a, b, c);
  return buf;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

/// The board of one view in the camera frame: centroid and unit normal towards the camera
/// (smallest principal axis of the circle points, which lie in the board plane).
struct BoardInCamera {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
};

BoardInCamera board_in_camera(const TargetView& view, const Eigen::Isometry3d& T) {
  BoardInCamera b;
  const auto& pts = view.lidar_circle_points;
  if (pts.empty()) return b;
  for (const auto& p : pts) b.centroid += T * p;
  b.centroid /= static_cast<double>(pts.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) {
    const Eigen::Vector3d d = T * p - b.centroid;
    scatter += d * d.transpose();
  }
  b.normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
  if (b.normal.dot(b.centroid) > 0) b.normal = -b.normal;
  return b;
}

/// Expected residual RMS [px] of a view at depth z: image edge noise and the LIDAR circle's
/// placement error seen at that depth, independent, added in quadrature.
double expected_px(const VerdictOptions& o, const core::PinholeCamera& camera, double depth_m) {
  const double f = 0.5 * (camera.intrinsics().fx + camera.intrinsics().fy);
  const double lidar_px = f * o.lidar_circle_sigma_m / std::max(depth_m, 1e-3);
  return std::hypot(o.image_edge_sigma_px, lidar_px);
}

/// RMS distance [px] between each LIDAR hole, projected with T (the centre of the ellipse
/// fitted to its projected circle, so the perspective shift of an ellipse's centre cancels)
/// and the centre of the image ellipse it is paired with. The two detectors order the holes
/// of a multi-hole board each from its own viewpoint, so the pairing is the one-to-one
/// assignment of least total squared distance (pair_holes_by_position). Sets `compared` to
/// the number of holes used.
double hole_reprojection_px(const TargetView& view, const core::PinholeCamera& camera, const Eigen::Isometry3d& T,
                            int* compared) {
  *compared = 0;
  const size_t n = std::min({view.lidar_centers.size(), view.lidar_normals.size(), view.image_ellipses.size()});
  std::vector<cv::Point2f> centres;  // of the projected LIDAR holes that project whole
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d normal = view.lidar_normals[k].normalized();
    Eigen::Vector3d e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
    std::vector<cv::Point2f> projected;
    for (int a = 0; a < 72; ++a) {
      const double t = 2.0 * M_PI * a / 72;
      const Eigen::Vector3d p = view.lidar_centers[k] + view.radius_m * (std::cos(t) * e1 + std::sin(t) * e2);
      Eigen::Vector2d px;
      if (!camera.project(T * p, &px)) break;
      projected.emplace_back(static_cast<float>(px.x()), static_cast<float>(px.y()));
    }
    if (projected.size() < 72) continue;
    centres.push_back(cv::fitEllipse(projected).center);
  }
  if (centres.empty()) return -1.0;
  std::vector<Eigen::Vector2d> points;
  for (const auto& c : centres) points.emplace_back(c.x, c.y);
  const std::vector<cv::RotatedRect> ellipses(view.image_ellipses.begin(), view.image_ellipses.begin() + n);
  const std::vector<size_t> pairing = pair_holes_by_position(points, ellipses);
  double best = 0.0;
  for (size_t i = 0; i < points.size(); ++i)
    best += (points[i] - Eigen::Vector2d(ellipses[pairing[i]].center.x, ellipses[pairing[i]].center.y)).squaredNorm();
  *compared = static_cast<int>(centres.size());
  return std::sqrt(best / *compared);
}

/// Physical rotation axis (camera frame) of a step `dr` of the rotation vector `r`:
/// log(Exp(r + h dr) Exp(r)^T) / h, so a direction of the parametrisation reads as a
/// rotation about an axis whatever the rotation itself.
Eigen::Vector3d physical_rotation(const Eigen::Vector3d& r, const Eigen::Vector3d& dr) {
  const double norm = dr.norm();
  if (norm < 1e-15) return Eigen::Vector3d::Zero();
  const double h = 1e-6 / norm;
  const Eigen::Matrix3d R0 = core::rotation_from_vector(r), R1 = core::rotation_from_vector(r + h * dr);
  return core::rotation_to_vector(R1 * R0.transpose()) / h;
}

/// "the translation along the board normal", "the rotation about the board's vertical axis", ...
/// with the advice that adds the missing constraint.
std::pair<std::string, std::string> direction_in_words(const Eigen::Vector3d& rotation_m,
                                                       const Eigen::Vector3d& translation_m,
                                                       const Eigen::Vector3d& normal) {
  const bool is_rotation = rotation_m.norm() > translation_m.norm();
  const Eigen::Vector3d v = (is_rotation ? rotation_m : translation_m).normalized();
  // In-plane axes: the camera's x (right) and the board's other in-plane direction.
  Eigen::Vector3d horizontal = Eigen::Vector3d::UnitX() - normal * normal.x();
  if (horizontal.norm() < 1e-6) horizontal = normal.unitOrthogonal();
  horizontal.normalize();
  const Eigen::Vector3d vertical = normal.cross(horizontal).normalized();
  const double c_n = std::abs(v.dot(normal)), c_h = std::abs(v.dot(horizontal)), c_v = std::abs(v.dot(vertical));
  std::string axis, advice;
  if (c_n >= c_h && c_n >= c_v) {
    axis = is_rotation ? "about the board normal" : "along the board normal";
    advice = is_rotation ? "add views spread across the image, or a board with more holes"
                         : "add a view at another depth or angle";
  } else {
    axis = std::string(is_rotation ? "about" : "along") + " the board's " + (c_h >= c_v ? "horizontal" : "vertical") +
           " in-plane axis";
    advice = is_rotation ? "add a view at another depth or with the board tilted"
                         : "add a view at another depth or elsewhere in the image";
  }
  return {std::string("the ") + (is_rotation ? "rotation " : "translation ") + axis, advice};
}

struct Findings {
  std::vector<VerdictReason> reasons;
  void add(VerdictLevel level, std::string text) { reasons.push_back({level, std::move(text)}); }
};

void check_plausibility(const EdgeAlignmentResult& r, const VerdictOptions& o, CalibrationVerdict& v,
                        Findings& f) {
  if (!r.T_camera_lidar.matrix().allFinite() || !std::isfinite(r.rms_px))
    f.add(VerdictLevel::kFail, "the estimate is not finite");
  if (!r.converged) f.add(VerdictLevel::kFail, "the solver did not converge (" + r.message + ")");
  if (v.used_views == 0) f.add(VerdictLevel::kFail, "every view was rejected as an outlier");
  v.translation_m = r.T_camera_lidar.translation().norm();
  if (!(v.translation_m <= o.max_translation_m))
    f.add(VerdictLevel::kFail, fmt("translation |t| = %.3f m exceeds the maximum of %.3f m (--max-translation)",
                                   v.translation_m, o.max_translation_m));
}

void check_views(const std::vector<TargetView>& views, const core::PinholeCamera& camera,
                 const EdgeAlignmentResult& r, const VerdictOptions& o, CalibrationVerdict& v, Findings& f) {
  double sum2 = 0, exp2 = 0, rep2 = 0, rep_exp2 = 0;
  int holes = 0;
  for (size_t k = 0; k < views.size(); ++k) {
    ViewVerdict& vv = v.views[k];
    const BoardInCamera board = board_in_camera(views[k], r.T_camera_lidar);
    vv.board_depth_m = board.centroid.z();
    vv.expected_px = expected_px(o, camera, vv.board_depth_m);
    vv.reprojection_px = hole_reprojection_px(views[k], camera, r.T_camera_lidar, &vv.holes_compared);
    if (!(vv.board_depth_m > 0)) {
      vv.problem = fmt("the board is behind the camera (depth %.2f m, expected > 0)", vv.board_depth_m);
      f.add(VerdictLevel::kFail, vv.name + ": " + vv.problem);
      continue;
    }
    if (!vv.used) {
      vv.problem = "rejected by the solver: " + r.views[k].reason;
      f.add(VerdictLevel::kWarn, vv.name + " was " + vv.problem);
      continue;
    }
    if (vv.rms_px > o.fail_ratio * vv.expected_px) {
      vv.problem = fmt("residual RMS %.2f px is more than %.0fx the %.2f px expected", vv.rms_px, o.fail_ratio,
                       vv.expected_px);
      f.add(VerdictLevel::kWarn, vv.name + ": " + vv.problem);
    }
    sum2 += vv.rms_px * vv.rms_px;
    exp2 += vv.expected_px * vv.expected_px;
    if (vv.holes_compared > 0) {
      rep2 += vv.reprojection_px * vv.reprojection_px * vv.holes_compared;
      rep_exp2 += vv.expected_px * vv.expected_px * vv.holes_compared;
      holes += vv.holes_compared;
      if (vv.reprojection_px > o.fail_ratio * vv.expected_px && vv.problem.empty()) {
        vv.problem = fmt("hole-centre reprojection %.2f px is more than %.0fx the %.2f px expected",
                         vv.reprojection_px, o.fail_ratio, vv.expected_px);
        f.add(VerdictLevel::kWarn, vv.name + ": " + vv.problem);
      }
    }
  }
  if (v.used_views == 0) return;
  v.rms_px = r.rms_px;
  v.expected_rms_px = std::sqrt(exp2 / v.used_views);
  const auto judge = [&](const std::string& what, double value, double expected) {
    const double ratio = value / expected;
    const bool fail = ratio > o.fail_ratio;
    if (!fail && !(ratio > o.warn_ratio)) return;
    f.add(fail ? VerdictLevel::kFail : VerdictLevel::kWarn,
          what + fmt(" %.2f px is %.1fx the %.2f px expected", value, ratio, expected) +
              fmt(fail ? " (FAIL beyond %.0fx)" : " (marginal beyond %.0fx)", fail ? o.fail_ratio : o.warn_ratio));
  };
  judge("residual RMS", v.rms_px, v.expected_rms_px);
  if (holes > 0) {
    v.reprojection_px = std::sqrt(rep2 / holes);
    v.expected_reprojection_px = std::sqrt(rep_exp2 / holes);
    judge("hole-centre reprojection RMS", v.reprojection_px, v.expected_reprojection_px);
  }
}

/// Leave-one-view-out: re-solves without each used view, from the estimate.
void check_agreement(const std::vector<TargetView>& views, const core::PinholeCamera& camera,
                     const EdgeAlignmentResult& r, const VerdictOptions& o, CalibrationVerdict& v, Findings& f) {
  std::vector<int> used;
  for (size_t k = 0; k < views.size(); ++k)
    if (v.views[k].used) used.push_back(static_cast<int>(k));
  if (used.size() < 3) {
    if (used.size() == 2)
      f.add(VerdictLevel::kWarn, "agreement between views not assessed: leave-one-view-out needs >= 3 views, 2 used");
    return;
  }
  EdgeAlignmentOptions opts = o.alignment;
  opts.reject_outlier_views = false;
  double mean_depth = 0;
  for (int k : used) mean_depth += v.views[k].board_depth_m / used.size();
  std::vector<double> moves;  // [cm at the mean board depth]
  std::vector<int> assessed;
  v.lovo_max_rotation_deg = v.lovo_max_translation_cm = 0;
  for (int k : used) {
    ViewVerdict& vv = v.views[k];
    std::vector<TargetView> subset;
    EdgeAlignmentOptions opts_k = opts;
    // The uncertainty of the estimate without view k is its model covariance (sandwich and
    // the LIDAR circles' terms): a jackknife of each subset would solve V - 1 more times per
    // view, V^2 solves in all, for a scatter that the full set's jackknife already has.
    opts_k.covariance_model.jackknife = false;
    opts_k.covariance_model.per_view.clear();
    const auto& per_view = opts.covariance_model.per_view;
    for (int j : used) {
      if (j == k) continue;
      subset.push_back(views[j]);
      // The holes' LIDAR sigmas follow their views (an empty entry: the default).
      opts_k.covariance_model.per_view.push_back(static_cast<size_t>(j) < per_view.size()
                                                     ? per_view[j]
                                                     : std::vector<LidarHoleSigma>{});
    }
    EdgeAlignmentResult rk;
    try {
      rk = align_edges(subset, camera, opts_k, r.T_camera_lidar);
    } catch (const std::exception& e) {
      vv.problem = std::string("without it the solve fails (") + e.what() + ")";
      f.add(VerdictLevel::kWarn, vv.name + ": " + vv.problem);
      continue;
    }
    const double rot = core::rotation_error_rad(rk.T_camera_lidar, r.T_camera_lidar);
    vv.lovo_rotation_deg = rot * 180.0 / M_PI;
    vv.lovo_translation_cm = core::translation_error_m(rk.T_camera_lidar, r.T_camera_lidar) * 100.0;
    if (rk.covariance_valid) {
      const core::Vector6d xk = core::to_vector6(rk.T_camera_lidar);  // rk.covariance's chart
      const core::Vector6d d = xk - core::to_vector6_near(r.T_camera_lidar, xk);
      vv.lovo_mahalanobis2 = d.dot(rk.covariance.ldlt().solve(d));
    }
    v.lovo_max_rotation_deg = std::max(v.lovo_max_rotation_deg, vv.lovo_rotation_deg);
    v.lovo_max_translation_cm = std::max(v.lovo_max_translation_cm, vv.lovo_translation_cm);
    moves.push_back(std::hypot(vv.lovo_translation_cm, rot * mean_depth * 100.0));
    assessed.push_back(k);
  }
  const double median_move = median(moves);
  for (size_t i = 0; i < assessed.size(); ++i) {
    ViewVerdict& vv = v.views[assessed[i]];
    const bool beyond_bounds = vv.lovo_rotation_deg > o.lovo_fail_deg || vv.lovo_translation_cm > o.lovo_fail_cm;
    const bool within_uncertainty = vv.lovo_mahalanobis2 >= 0 && vv.lovo_mahalanobis2 <= o.lovo_chi2_bound;
    if (beyond_bounds && within_uncertainty) {
      vv.problem = fmt("without it the estimate moves %.2f deg and %.1f cm", vv.lovo_rotation_deg,
                       vv.lovo_translation_cm) +
                   fmt(", within the uncertainty of the estimate without it (squared Mahalanobis %.1f <= %.2f):",
                       vv.lovo_mahalanobis2, o.lovo_chi2_bound) +
                   " the views agree, but each pins the transform only loosely";
      f.add(VerdictLevel::kWarn, vv.name + ": " + vv.problem);
    } else if (beyond_bounds) {
      vv.problem = fmt("without it the estimate moves %.2f deg and %.1f cm", vv.lovo_rotation_deg,
                       vv.lovo_translation_cm) +
                   fmt(" (FAIL beyond %.1f deg or %.1f cm): the views disagree", o.lovo_fail_deg, o.lovo_fail_cm);
      f.add(VerdictLevel::kFail, vv.name + ": " + vv.problem);
    } else if (vv.lovo_mahalanobis2 > o.lovo_chi2_bound && moves[i] > o.lovo_influence_ratio * median_move) {
      vv.lovo_influential = true;
      vv.problem = fmt("without it the estimate moves %.3f deg and %.2f cm, beyond its uncertainty", vv.lovo_rotation_deg,
                       vv.lovo_translation_cm) +
                   fmt(" (squared Mahalanobis %.1f > %.2f) and %.1fx the median move of the views",
                       vv.lovo_mahalanobis2, o.lovo_chi2_bound, moves[i] / std::max(median_move, 1e-12));
      f.add(VerdictLevel::kWarn, vv.name + ": " + vv.problem);
    }
  }
}

/// The weakest direction of the estimate, as the motion it causes at the boards: a step
/// (dr, dt) of to_vector6 moves a camera-frame point x by w x (x - t) + dt with w = Jl dr,
/// i.e. by J_x (dr, dt). Over the circle points x of the used views, M = mean J_x^T J_x, so
/// a deviation d of the parameters moves them by sqrt(d^T M d) RMS. With C = L L^T the
/// covariance, the 1-sigma deviations are d = L z, |z| = 1, and the largest RMS motion is
/// sqrt(lambda_max(L^T M L)) along d = L z_max (the smallest is the strongest direction's).
/// A rotation about the viewing direction moves the boards by its angle times their offset
/// from the axis, a rotation about an in-plane axis by its angle times their depth: this is
/// what a colouring error at the boards' distance is made of.
void check_observability(const std::vector<TargetView>& views, const EdgeAlignmentResult& r,
                         const VerdictOptions& o, CalibrationVerdict& v, Findings& f) {
  if (v.used_views == 0) return;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < views.size(); ++k) {
    if (!v.views[k].used) continue;
    normal += board_in_camera(views[k], r.T_camera_lidar).normal;
  }
  normal = normal.norm() > 1e-9 ? normal.normalized() : Eigen::Vector3d(0, 0, -1);
  const std::string one = v.used_views == 1 ? "one view: " : "";
  if (!r.covariance_valid || !r.covariance.allFinite()) {
    f.add(VerdictLevel::kWarn, one + "the covariance is not available (the information matrix is singular): "
                                     "some direction is not constrained; add views at other depths and angles");
    return;
  }
  const Eigen::Vector3d r0 = core::to_vector6(r.T_camera_lidar).head<3>();
  Eigen::Matrix3d Jl;
  for (int i = 0; i < 3; ++i) Jl.col(i) = physical_rotation(r0, Eigen::Vector3d::Unit(i));
  const Eigen::Vector3d t = r.T_camera_lidar.translation();
  // Second moments of the lever arms: mean J_x^T J_x needs only mean(l) and mean(l l^T)
  // of l = x - t, since |w x l + dt|^2 is quadratic in l.
  Eigen::Vector3d mean_l = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mean_llt = Eigen::Matrix3d::Zero();
  size_t count = 0;
  for (size_t k = 0; k < views.size(); ++k) {
    if (!v.views[k].used) continue;
    for (const auto& p : views[k].lidar_circle_points) {
      const Eigen::Vector3d l = r.T_camera_lidar * p - t;
      mean_l += l;
      mean_llt += l * l.transpose();
      ++count;
    }
  }
  if (count == 0) return;
  mean_l /= static_cast<double>(count);
  mean_llt /= static_cast<double>(count);
  // |w x l + dt|^2 = w^T (|l|^2 I - l l^T) w + 2 dt^T (w x l) + |dt|^2; w x l = -[l]x w.
  Eigen::Matrix3d cross_mean;
  cross_mean << 0, -mean_l.z(), mean_l.y(), mean_l.z(), 0, -mean_l.x(), -mean_l.y(), mean_l.x(), 0;
  core::Matrix6d M = core::Matrix6d::Zero();
  M.topLeftCorner<3, 3>() = Jl.transpose() * (mean_llt.trace() * Eigen::Matrix3d::Identity() - mean_llt) * Jl;
  M.bottomLeftCorner<3, 3>() = -cross_mean * Jl;
  M.topRightCorner<3, 3>() = M.bottomLeftCorner<3, 3>().transpose();
  M.bottomRightCorner<3, 3>().setIdentity();
  // The geometry's covariance: the model terms without the jackknife, whose leave-one-out
  // scatter measures the views' agreement (check_agreement judges that) and, dominated by the
  // most leveraged view, overstates every direction alike. With 1-2 views the total is the
  // model (its resampled term is the systematic one without linearisation).
  const CovarianceTerms& terms = r.covariance_terms;
  const core::Matrix6d model = terms.valid && !terms.resampled_used
                                   ? core::Matrix6d(terms.sandwich + terms.systematic)
                                   : r.covariance;
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> cov_eig(model.allFinite() ? model : r.covariance);
  const core::Matrix6d L =
      cov_eig.eigenvectors() * cov_eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eig(L.transpose() * M * L);
  v.weakest_sigma_m = std::sqrt(std::max(eig.eigenvalues()(5), 0.0));
  v.strongest_sigma_m = std::sqrt(std::max(eig.eigenvalues()(0), 0.0));
  // Name the weakest deviation by its larger part: the RMS motion its rotation alone causes
  // at the boards against its translation.
  const core::Vector6d d = L * eig.eigenvectors().col(5);
  const Eigen::Vector3d w = Jl * d.head<3>();
  const double rotation_motion =
      std::sqrt(std::max(0.0, w.dot((mean_llt.trace() * Eigen::Matrix3d::Identity() - mean_llt) * w)));
  const Eigen::Vector3d rotation_m = w.norm() > 0 ? Eigen::Vector3d(w.normalized() * rotation_motion) : w;
  const auto [words, advice] = direction_in_words(rotation_m, d.tail<3>(), normal);
  v.weakest_direction = words;
  const std::string numbers = fmt(" (1-sigma %.2f cm at the board, WARN beyond %.2f cm; the strongest direction's is",
                                  v.weakest_sigma_m * 100, o.weak_sigma_m * 100) +
                              fmt(" %.3f cm)", v.strongest_sigma_m * 100);
  if (v.used_views == 1 || v.weakest_sigma_m > o.weak_sigma_m)
    f.add(VerdictLevel::kWarn, one + words + " is weakly constrained" + numbers + "; " + advice);
}

}  // namespace

std::string to_string(VerdictLevel level) {
  switch (level) {
    case VerdictLevel::kPass: return "PASS";
    case VerdictLevel::kWarn: return "WARN";
    case VerdictLevel::kFail: return "FAIL";
  }
  return "?";
}

std::string VerdictOptions::validate() const {
  if (!(max_translation_m > 0)) return "max_translation_m must be > 0, got " + std::to_string(max_translation_m);
  if (!(image_edge_sigma_px > 0) || !(lidar_circle_sigma_m >= 0))
    return "image_edge_sigma_px must be > 0 and lidar_circle_sigma_m >= 0";
  if (!(warn_ratio >= 1) || !(fail_ratio > warn_ratio)) return "need 1 <= warn_ratio < fail_ratio";
  if (!(lovo_fail_deg > 0) || !(lovo_fail_cm > 0)) return "lovo_fail_deg and lovo_fail_cm must be > 0";
  if (!(lovo_chi2_bound > 0) || !(lovo_influence_ratio >= 1) || !(weak_sigma_m > 0))
    return "lovo_chi2_bound and weak_sigma_m must be > 0, lovo_influence_ratio >= 1";
  return alignment.validate();
}

std::string CalibrationVerdict::summary() const {
  std::string s = to_string(level);
  for (size_t i = 0; i < reasons.size(); ++i) s += (i ? "; " : ": ") + reasons[i].text;
  return s;
}

CalibrationVerdict judge_calibration(const std::vector<TargetView>& views, const core::PinholeCamera& camera,
                                     const EdgeAlignmentResult& result, const VerdictOptions& options) {
  if (const std::string why = options.validate(); !why.empty())
    throw std::invalid_argument("judge_calibration: " + why);
  if (result.views.size() != views.size())
    throw std::invalid_argument("judge_calibration: the result has " + std::to_string(result.views.size()) +
                                " views, expected the " + std::to_string(views.size()) + " given");
  CalibrationVerdict v;
  v.views.resize(views.size());
  for (size_t k = 0; k < views.size(); ++k) {
    v.views[k].name = views[k].name;
    v.views[k].used = result.views[k].used;
    v.views[k].rms_px = result.views[k].rms_px;
    v.used_views += result.views[k].used ? 1 : 0;
  }
  Findings f;
  check_plausibility(result, options, v, f);
  const bool finite = result.T_camera_lidar.matrix().allFinite();
  if (finite) check_views(views, camera, result, options, v, f);
  // Leave-one-view-out only re-solves an estimate that has not failed already: from a pose
  // behind the board, far off the rig or far off the edges, each solve is long and adds nothing.
  bool plausible = finite && result.converged;
  for (const auto& reason : f.reasons) plausible = plausible && reason.level != VerdictLevel::kFail;
  if (plausible) check_agreement(views, camera, result, options, v, f);
  if (finite) check_observability(views, result, options, v, f);
  if (!result.initial_guess_ambiguity.empty())
    f.add(VerdictLevel::kWarn, "the start pose is ambiguous: " + result.initial_guess_ambiguity +
                                   "; a view at another board pose, or a rough guess, decides it");
  std::stable_sort(f.reasons.begin(), f.reasons.end(),
                   [](const VerdictReason& a, const VerdictReason& b) { return a.level > b.level; });
  v.reasons = std::move(f.reasons);
  for (const auto& reason : v.reasons) v.level = std::max(v.level, reason.level);
  return v;
}

std::string format_verdict_report(const CalibrationVerdict& v) {
  std::ostringstream os;
  os << std::fixed << "**Verdict: " << to_string(v.level) << "**";
  if (v.reasons.empty()) os << " (every check within its threshold)";
  os << "\n\n";
  for (const auto& reason : v.reasons) os << "- " << to_string(reason.level) << ": " << reason.text << "\n";
  if (!v.reasons.empty()) os << "\n";
  os << std::setprecision(2) << "- residual RMS " << v.rms_px << " px, expected " << v.expected_rms_px << " px\n";
  if (v.reprojection_px >= 0)
    os << "- hole-centre reprojection RMS " << v.reprojection_px << " px, expected " << v.expected_reprojection_px
       << " px\n";
  if (v.lovo_max_rotation_deg >= 0)
    os << "- leave-one-view-out: the estimate moves at most " << std::setprecision(3) << v.lovo_max_rotation_deg
       << " deg and " << std::setprecision(2) << v.lovo_max_translation_cm << " cm\n";
  os << "- |t| = " << std::setprecision(3) << v.translation_m << " m\n";
  if (v.weakest_sigma_m >= 0)
    os << "- weakest direction: " << v.weakest_direction << ", 1-sigma " << std::setprecision(3)
       << v.weakest_sigma_m * 100 << " cm at the board (strongest " << v.strongest_sigma_m * 100 << " cm)\n";
  os << "\n| view | used | depth [m] | RMS [px] | expected [px] | holes | centre reproj. [px] | LOVO [deg] | "
        "LOVO [cm] | problem |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& vv : v.views) {
    os << "| " << vv.name << " | " << (vv.used ? "yes" : "**no**") << " | " << std::setprecision(2)
       << vv.board_depth_m << " | " << vv.rms_px << " | " << vv.expected_px << " | " << vv.holes_compared << " | ";
    if (vv.reprojection_px >= 0) os << vv.reprojection_px;
    else os << "n/a";
    os << " | ";
    if (vv.lovo_rotation_deg >= 0) os << std::setprecision(3) << vv.lovo_rotation_deg << " | " << std::setprecision(2) << vv.lovo_translation_cm;
    else os << "n/a | n/a";
    os << " | " << (vv.problem.empty() ? "" : "**" + vv.problem + "**") << " |\n";
  }
  os << "\n";
  return os.str();
}

}  // namespace rgbdt::extrinsics
