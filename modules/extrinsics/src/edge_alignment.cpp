#include "rgbdt/extrinsics/edge_alignment.hpp"

#include <ceres/ceres.h>
#include <ceres/cubic_interpolation.h>
#include <ceres/rotation.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "covariance_input.hpp"
#include "edge_cost.hpp"
#include "lm_polish.hpp"
#include "projection.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/extrinsics/hole_pairing.hpp"
#include "rgbdt/extrinsics/initial_guess.hpp"

namespace rgbdt::extrinsics {

namespace detail {

ProjectionModel make_projection_model(const core::PinholeCamera& camera) {
  const core::CameraIntrinsics& in = camera.intrinsics();
  ProjectionModel m;
  m.model = in.model;
  m.k[0] = in.fx;
  m.k[1] = in.fy;
  m.k[2] = in.cx;
  m.k[3] = in.cy;
  for (size_t i = 0; i < in.distortion.size() && i < 5; ++i) m.d[i] = in.distortion[i];
  m.width = in.width;
  m.height = in.height;
  bool any = false;
  for (double c : m.d) any = any || c != 0.0;
  if (in.model == core::DistortionModel::kNone || !any) return m;
  // Normalised radius of the image corners, with some room for points just outside.
  double r_image = 0.0;
  for (const auto& px : {Eigen::Vector2d(0, 0), Eigen::Vector2d(in.width - 1, 0),
                         Eigen::Vector2d(0, in.height - 1),
                         Eigen::Vector2d(in.width - 1, in.height - 1)}) {
    r_image = std::max(r_image, camera.unproject(px).head<2>().norm());
  }
  m.r_max = 1.25 * r_image;
  // Stop before the distorted radius stops growing (polynomial fold-back).
  double prev = 0.0;
  for (int i = 1; i <= 400; ++i) {
    const double r = m.r_max * i / 400.0;
    double xd, yd;
    core::distort_generic(m.model, m.d, r, 0.0, &xd, &yd);
    if (xd <= prev) {
      m.r_max = m.r_max * (i - 1) / 400.0;
      break;
    }
    prev = xd;
  }
  return m;
}

}  // namespace detail

namespace {

using detail::ProjectionModel;
using detail::SmoothView;
using detail::transform_point;
using detail::ViewEdgeCost;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Coarse stage: hole centres projected against the ellipse centres. Its basin is wide
/// (a PnP refinement), so it brings a poor guess near enough for Eq. (2), whose
/// nearest-edge attraction alone can shrink a far-off circle onto the near side of its
/// image (a local minimum along the optical axis).
struct CenterResidual {
  CenterResidual(const ProjectionModel* cam, Eigen::Vector3d c, Eigen::Vector2d px)
      : cam_(cam), center_(std::move(c)), px_(std::move(px)) {}
  template <typename T>
  bool operator()(const T* x, T* residual) const {
    T p_camera[3], uv[2];
    transform_point(x, center_, p_camera);
    detail::project_total(*cam_, p_camera, uv);
    residual[0] = uv[0] - T(px_.x());
    residual[1] = uv[1] - T(px_.y());
    return true;
  }
  const ProjectionModel* cam_;
  Eigen::Vector3d center_;
  Eigen::Vector2d px_;
};

/// The paper's look-up table (Sec. 3.6): distance transform of the rasterised edges and,
/// per pixel reached by a projection, a least-squares plane over the 10x10 window around it.
class PaperPlaneLut {
 public:
  PaperPlaneLut(const std::vector<Eigen::Vector2d>& edges, int width, int height, int window)
      : width_(width), height_(height), window_(window) {
    cv::Mat edge_image(height, width, CV_8U, cv::Scalar(255));
    for (const auto& p : edges) {
      const int u = static_cast<int>(std::lround(p.x()));
      const int v = static_cast<int>(std::lround(p.y()));
      if (u >= 0 && v >= 0 && u < width && v < height) edge_image.at<uint8_t>(v, u) = 0;
    }
    cv::distanceTransform(edge_image, dt_, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
    planes_.resize(static_cast<size_t>(width) * height);
    known_.assign(static_cast<size_t>(width) * height, 0);
  }

  /// Plane value at a continuous pixel: the plane of the nearest pixel (clamped to the
  /// image) evaluated at (u, v), so central differences see a slope.
  double value(double u, double v) const {
    const int iu = std::clamp(static_cast<int>(std::lround(u)), 0, width_ - 1);
    const int iv = std::clamp(static_cast<int>(std::lround(v)), 0, height_ - 1);
    const size_t idx = static_cast<size_t>(iv) * width_ + iu;
    if (!known_[idx]) {
      planes_[idx] = fit_plane(iu, iv);
      known_[idx] = 1;
    }
    const Eigen::Vector3d& pl = planes_[idx];
    return pl[0] * (u - iu) + pl[1] * (v - iv) + pl[2];
  }

 private:
  // z = a (x - iu) + b (y - iv) + c over the window, least squares.
  Eigen::Vector3d fit_plane(int iu, int iv) const {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    const int lo = -window_ / 2, hi = lo + window_ - 1;
    for (int dv = lo; dv <= hi; ++dv) {
      for (int du = lo; du <= hi; ++du) {
        const int u = std::clamp(iu + du, 0, width_ - 1);
        const int v = std::clamp(iv + dv, 0, height_ - 1);
        const Eigen::Vector3d row(u - iu, v - iv, 1.0);
        A += row * row.transpose();
        rhs += row * static_cast<double>(dt_.at<float>(v, u));
      }
    }
    return A.ldlt().solve(rhs);
  }
  int width_, height_, window_;
  cv::Mat dt_;
  mutable std::vector<Eigen::Vector3d> planes_;
  mutable std::vector<uint8_t> known_;
};

struct PaperEdgeResidual {
  PaperEdgeResidual(const ProjectionModel* cam, const PaperPlaneLut* lut, Eigen::Vector3d p)
      : cam_(cam), lut_(lut), p_lidar_(std::move(p)) {}
  bool operator()(const double* x, double* residual) const {
    double p_camera[3], uv[2];
    transform_point(x, p_lidar_, p_camera);
    detail::project_total(*cam_, p_camera, uv);
    residual[0] = lut_->value(uv[0], uv[1]);
    return true;
  }
  const ProjectionModel* cam_;
  const PaperPlaneLut* lut_;
  Eigen::Vector3d p_lidar_;
};

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

/// Fit of a view's points at x (Huber-free distances, points in the image) and, when ne is
/// not null, the normal equations there (their JtJ_plain() is the covariance's).
detail::PointFit fit_of_view(const std::vector<Eigen::Vector3d>& points, const SmoothView& view,
                             const ProjectionModel& cam, double huber_px, const core::Vector6d& x,
                             detail::NormalEquations* ne) {
  detail::PointFit fit;
  ViewEdgeCost(&cam, &view, &points, huber_px).accumulate(x.data(), ne, &fit);
  return fit;
}

/// The LM polish's stopping rules from the options (the solve's own adds Ceres's gradient
/// tolerance).
detail::PolishOptions polish_options_of(const EdgeAlignmentOptions& options) {
  detail::PolishOptions polish_options;
  polish_options.max_iterations = options.max_iterations;
  polish_options.parameter_tolerance = options.parameter_tolerance;
  polish_options.step_tolerance_sigma = options.step_tolerance_sigma;
  polish_options.rejected_step_sigma = 5.0 * options.step_tolerance_sigma;
  return polish_options;
}

/// The used views' re-solves from x on `resamples` seeded draws of their circles' LIDAR
/// errors (covariance.hpp, `resampled`): each solution's deviation from x.
std::vector<core::Vector6d> resampled_deviations(const std::vector<TargetView>& views,
                                                 const std::vector<size_t>& used,
                                                 const std::vector<const SmoothView*>& fields,
                                                 const std::vector<const std::vector<LidarHoleSigma>*>& sigmas,
                                                 const ProjectionModel& cam, const core::Vector6d& x,
                                                 const EdgeAlignmentOptions& options) {
  const CovarianceOptions& model = options.covariance_model;
  std::mt19937_64 rng(20261207);
  std::vector<std::vector<Eigen::Vector3d>> points(used.size());
  std::vector<std::unique_ptr<ViewEdgeCost>> costs;
  std::vector<const ViewEdgeCost*> all;
  for (size_t c = 0; c < used.size(); ++c) {
    costs.push_back(std::make_unique<ViewEdgeCost>(&cam, fields[c], &points[c], options.huber_px));
    all.push_back(costs.back().get());
  }
  std::vector<core::Vector6d> deviations;
  for (int draw = 0; draw < model.resamples; ++draw) {
    for (size_t c = 0; c < used.size(); ++c)
      points[c] = detail::perturbed_circle_points(views[used[c]], sigmas[c], model.default_range_sigma_m, &rng);
    deviations.push_back(detail::polish(all, x, polish_options_of(options)).x - x);
  }
  return deviations;
}

/// The jackknife's solutions without each view in turn, from the solution x: one
/// Gauss-Newton step on the other views' normal equations at x (CovarianceOptions::
/// jackknife_one_step), else, or where that system is singular, an LM polish of them.
/// at_x: each cost's normal equations at x when the solve's last pass left them (else null).
std::vector<core::Vector6d> leave_one_view_out(const std::vector<std::unique_ptr<ViewEdgeCost>>& costs,
                                               const std::vector<detail::NormalEquations>* at_x,
                                               const core::Vector6d& x, const EdgeAlignmentOptions& options) {
  std::vector<detail::NormalEquations> ne(costs.size());
  detail::NormalEquations all;
  if (options.covariance_model.jackknife_one_step) {
    detail::PointFit fit;
    for (size_t c = 0; c < costs.size(); ++c) {
      if (at_x != nullptr) ne[c] = (*at_x)[c];
      else costs[c]->accumulate(x.data(), &ne[c], &fit);
      all += ne[c];
    }
  }
  std::vector<core::Vector6d> out;
  for (size_t v = 0; v < costs.size(); ++v) {
    if (options.covariance_model.jackknife_one_step) {
      const Eigen::LDLT<core::Matrix6d> others(all.JtJ - ne[v].JtJ);
      const core::Vector6d step = others.solve(ne[v].Jtr - all.Jtr);
      if (others.info() == Eigen::Success && others.isPositive() && step.allFinite()) {
        out.push_back(x + step);
        continue;
      }
    }
    std::vector<const ViewEdgeCost*> others;
    for (size_t j = 0; j < costs.size(); ++j)
      if (j != v) others.push_back(costs[j].get());
    out.push_back(detail::polish(others, x, polish_options_of(options)).x);
  }
  return out;
}

/// The solve's last pass over the active views (ours, coarse-to-fine), at x: the solution,
/// or where the polish took its last, too short to evaluate, step from (PolishResult::
/// x_evaluated). Per usable view, its normal equations and points, valid where the view was
/// in that pass.
struct PassAtSolution {
  core::Vector6d x;
  std::vector<detail::NormalEquations> normal_equations;
  std::vector<detail::PointJacobians> points;
};

/// The covariance of the solution x (covariance.hpp) over the active views; the jackknife's
/// leave-one-view-out solutions and the few-view re-solves use Eq. (2) (our cost, whatever
/// the method) from x. at_x: the solve's last pass, or null (a pass here at x_solution);
/// the covariance is taken where that pass was (within step_tolerance_sigma of the solution).
CovarianceTerms covariance_at_solution(const std::vector<TargetView>& views,
                                       const std::vector<size_t>& usable_index,
                                       const std::vector<bool>& active,
                                       const std::vector<std::unique_ptr<SmoothView>>& all_fields,
                                       const ProjectionModel& cam, const core::Vector6d& x_solution,
                                       const EdgeAlignmentOptions& options, const PassAtSolution* at_x) {
  const core::Vector6d& x = at_x != nullptr ? at_x->x : x_solution;
  const CovarianceOptions& model = options.covariance_model;
  std::vector<size_t> used;
  std::vector<const SmoothView*> fields;
  std::vector<const std::vector<LidarHoleSigma>*> sigmas;
  std::vector<detail::NormalEquations> ne_at_x;
  std::vector<const detail::PointJacobians*> points_at_x;
  for (size_t k = 0; k < usable_index.size(); ++k) {
    if (!active[k]) continue;
    const size_t i = usable_index[k];
    used.push_back(i);
    fields.push_back(all_fields[k].get());
    sigmas.push_back(i < model.per_view.size() ? &model.per_view[i] : nullptr);
    if (at_x != nullptr) {
      ne_at_x.push_back(at_x->normal_equations[k]);
      points_at_x.push_back(&at_x->points[k]);
    }
  }
  std::vector<detail::ViewCovarianceInput> inputs;
  std::vector<std::unique_ptr<ViewEdgeCost>> costs;
  for (size_t c = 0; c < used.size(); ++c) {
    inputs.push_back(at_x != nullptr ? detail::view_covariance_input(*points_at_x[c], views[used[c]], x, sigmas[c],
                                                                     model.default_range_sigma_m)
                                     : detail::view_covariance_input(cam, *fields[c], views[used[c]], x, sigmas[c],
                                                                     model.default_range_sigma_m));
    costs.push_back(std::make_unique<ViewEdgeCost>(&cam, fields[c], &views[used[c]].lidar_circle_points,
                                                   options.huber_px));
  }
  std::vector<core::Vector6d> leave_one_out;
  if (model.jackknife && costs.size() >= 3)
    leave_one_out = leave_one_view_out(costs, at_x != nullptr ? &ne_at_x : nullptr, x, options);
  std::vector<core::Vector6d> resampled;
  if (model.resamples > 0 && !used.empty() && used.size() < 3)
    resampled = resampled_deviations(views, used, fields, sigmas, cam, x, options);
  return detail::combine_covariance(inputs, leave_one_out, resampled);
}

std::string usable_reason(const TargetView& view, const core::PinholeCamera& camera) {
  std::ostringstream os;
  if (view.lidar_circle_points.empty()) os << "no LIDAR circle points";
  else if (view.image_edge_points_px.size() < 8)
    os << "only " << view.image_edge_points_px.size() << " image edge points (expected >= 8)";
  else if ((view.image_width != 0 && view.image_width != camera.width()) ||
           (view.image_height != 0 && view.image_height != camera.height()))
    os << "image is " << view.image_width << " x " << view.image_height
       << " px but the camera is " << camera.width() << " x " << camera.height();
  else {
    for (const auto& p : view.lidar_circle_points)
      if (!p.allFinite()) return "non-finite LIDAR circle point";
    for (const auto& p : view.image_edge_points_px)
      if (!p.allFinite()) return "non-finite image edge point";
  }
  return os.str();
}

std::string view_label(const TargetView& view, size_t i) {
  return view.name.empty() ? "view " + std::to_string(i) : view.name;
}

/// Fills result->views with each view's label, point count and, when it cannot be used, the
/// reason; returns the indices of the usable views. Throws when none is usable.
std::vector<size_t> label_views(const std::vector<TargetView>& views,
                                const core::PinholeCamera& camera, EdgeAlignmentResult* result) {
  result->views.resize(views.size());
  std::vector<size_t> usable_index;
  std::ostringstream reasons;
  for (size_t i = 0; i < views.size(); ++i) {
    ViewResidual& vr = result->views[i];
    vr.name = view_label(views[i], i);
    vr.num_points = static_cast<int>(views[i].lidar_circle_points.size());
    vr.reason = usable_reason(views[i], camera);
    vr.used = vr.reason.empty();
    if (vr.used) {
      usable_index.push_back(i);
    } else {
      reasons << vr.name << ": " << vr.reason << "; ";
    }
  }
  if (usable_index.empty()) {
    throw std::invalid_argument("align_edges: no usable view among " +
                                std::to_string(views.size()) + " (" + reasons.str() + ")");
  }
  return usable_index;
}

/// result->T_camera_lidar_initial: the guess when one is given, else the closed-form guess
/// over the usable views (throws when that fails).
void set_initial_pose(const std::vector<TargetView>& views, const std::vector<size_t>& usable_index,
                      const core::PinholeCamera& camera,
                      const std::optional<Eigen::Isometry3d>& T_camera_lidar_guess,
                      EdgeAlignmentResult* result) {
  if (T_camera_lidar_guess) {
    result->T_camera_lidar_initial = *T_camera_lidar_guess;
    return;
  }
  // Copy the views only when some are unusable.
  std::vector<TargetView> usable_views;
  if (usable_index.size() != views.size()) {
    for (size_t i : usable_index) usable_views.push_back(views[i]);
  }
  const InitialGuessResult guess =
      closed_form_initial_guess(usable_views.empty() ? views : usable_views, camera);
  if (!guess.ok) {
    throw std::invalid_argument(
        "align_edges: no initial guess given and the closed-form "
        "guess failed: " +
        guess.message);
  }
  result->T_camera_lidar_initial = guess.T_camera_lidar;
  result->initial_from_closed_form = true;
  core::log_info("extrinsics: closed-form initial guess (", guess.message, ")");
  if (guess.ambiguous) {
    result->initial_guess_ambiguity = guess.ambiguity;
    core::log_warning("extrinsics: ", guess.ambiguity);
  }
}

/// What the solves read of each usable view (indexed like usable_index).
struct ViewFields {
  std::vector<std::unique_ptr<SmoothView>> fields;
  std::vector<std::unique_ptr<PaperPlaneLut>> luts;  ///< the paper's method only
  // Coarse-to-fine (ours): every coarse_stride-th circle point of each view.
  std::vector<std::vector<Eigen::Vector3d>> coarse_points;
};

/// Adds the wall time of the paper's LUTs to *paper_luts_s.
ViewFields build_view_fields(const std::vector<TargetView>& views,
                             const std::vector<size_t>& usable_index,
                             const core::PinholeCamera& camera,
                             const EdgeAlignmentOptions& options, double* paper_luts_s) {
  const bool paper = options.method == EdgeAlignmentMethod::kPaperPlaneFit;
  ViewFields out;
  out.coarse_points.resize(usable_index.size());
  for (size_t k = 0; k < usable_index.size(); ++k) {
    const TargetView& v = views[usable_index[k]];
    // The exact field also measures the per-view fit of the paper's method, so that both
    // methods are reported on the same scale.
    out.fields.push_back(std::make_unique<SmoothView>(v.image_edge_points_px, options.field));
    if (paper) {
      const auto t0 = std::chrono::steady_clock::now();
      out.luts.push_back(std::make_unique<PaperPlaneLut>(v.image_edge_points_px, camera.width(),
                                                         camera.height(), options.paper_window_px));
      *paper_luts_s += seconds_since(t0);
    } else if (options.coarse_stride > 1) {
      const auto& all = v.lidar_circle_points;
      for (size_t i = 0; i < all.size(); i += static_cast<size_t>(options.coarse_stride))
        out.coarse_points[k].push_back(all[i]);
    }
  }
  return out;
}

/// The coarse stage (CenterResidual) from *x; returns its LM iterations (none when fewer
/// than 3 holes pair up).
int align_hole_centers(const std::vector<TargetView>& views,
                       const std::vector<size_t>& usable_index, const ProjectionModel& cam,
                       core::Vector6d* x) {
  ceres::Problem problem;
  int holes = 0;
  // Holes paired by position at the start pose, not by the detectors' order.
  const Eigen::Isometry3d T0 = core::from_vector6(*x);
  for (size_t k : usable_index) {
    const TargetView& v = views[k];
    if (v.lidar_centers.size() > v.image_ellipses.size()) continue;
    std::vector<Eigen::Vector2d> start_px;
    for (const Eigen::Vector3d& c : v.lidar_centers) {
      const Eigen::Vector3d pc = T0 * c;
      Eigen::Vector2d p;
      project_total(cam, pc.data(), p.data());
      start_px.push_back(p);
    }
    const std::vector<size_t> pairing = pair_holes_by_position(start_px, v.image_ellipses);
    for (size_t h = 0; h < start_px.size(); ++h) {
      const cv::Point2f& c = v.image_ellipses[pairing[h]].center;
      const Eigen::Vector2d px(c.x, c.y);
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CenterResidual, 2, 6>(
                                   new CenterResidual(&cam, v.lidar_centers[h], px)),
                               new ceres::HuberLoss(20.0), x->data());
      ++holes;
    }
  }
  if (holes < 3) return 0;  // fewer leave the pose unconstrained; go straight to Eq. (2)
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = 50;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary s;
  ceres::Solve(o, &problem, &s);
  return s.num_successful_steps + s.num_unsuccessful_steps;
}

/// Ceres' Levenberg-Marquardt for Eq. (2).
ceres::Solver::Options edge_solver_options(const EdgeAlignmentOptions& options) {
  ceres::Solver::Options solver_options;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.gradient_tolerance = 1e-14;
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  return solver_options;
}

/// What every round of Eq. (2) reads.
struct AlignmentProblem {
  const std::vector<TargetView>& views;
  const std::vector<size_t>& usable_index;
  const ProjectionModel& cam;
  const ViewFields& fields;
  const EdgeAlignmentOptions& options;
  const ceres::Solver::Options& solver_options;
};

/// The usable views across the outlier-rejection rounds (indexed like usable_index).
struct RoundState {
  explicit RoundState(size_t n)
      : active(n, true), sum2_of_view(n, 0.0), count_of_view(n, 0), fit_at_x(n) {}
  std::vector<bool> active;
  std::vector<double> sum2_of_view;
  std::vector<size_t> count_of_view;
  // Fit of each view at this round's x, when the polish left it.
  std::vector<detail::PointFit> fit_at_x;
  // The polish's last pass (ours with the covariance; else none): the active views' sums
  // and points at x, so that the covariance needs no pass of its own.
  std::optional<PassAtSolution> pass_at_x;
};

/// Our LM (detail::polish) from x over the active views, on each view's coarse subset or on
/// all its circle points.
detail::PolishResult polish_active_views(const AlignmentProblem& p, const RoundState& state, bool coarse,
                                         const detail::PolishOptions& polish_options, const core::Vector6d& x) {
  std::vector<std::unique_ptr<ViewEdgeCost>> costs;
  std::vector<const ViewEdgeCost*> cost_pointers;
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    if (!state.active[k]) continue;
    const auto& points = coarse ? p.fields.coarse_points[k] : p.views[p.usable_index[k]].lidar_circle_points;
    costs.push_back(std::make_unique<ViewEdgeCost>(&p.cam, p.fields.fields[k].get(), &points, p.options.huber_px));
    cost_pointers.push_back(costs.back().get());
  }
  return detail::polish(cost_pointers, x, polish_options);
}

/// One round of Eq. (2), ours coarse-to-fine, from *x over the active views: fills
/// state->fit_at_x and *have_fit for them; returns the solve's report.
std::string solve_coarse_then_polish(const AlignmentProblem& p, RoundState* state,
                                     std::vector<bool>* have_fit, core::Vector6d* x,
                                     EdgeAlignmentResult* result) {
  // Levenberg-Marquardt from the (possibly poor) start on the coarse subset, then on all
  // points from inside the basin, with the same tolerances, on 6x6 normal equations
  // accumulated point by point; the last pass also gives the per-view fit and what the
  // covariance reads.
  detail::PolishOptions polish_options = polish_options_of(p.options);
  polish_options.gradient_tolerance = p.solver_options.gradient_tolerance;
  const detail::PolishResult coarse = polish_active_views(p, *state, true, polish_options, *x);
  polish_options.keep_point_jacobians = p.options.compute_covariance;
  detail::PolishResult polished = polish_active_views(p, *state, false, polish_options, coarse.x);
  *x = polished.x;
  result->iterations += coarse.iterations + polished.iterations;
  result->converged = coarse.converged && polished.converged;
  state->pass_at_x.reset();
  if (polish_options.keep_point_jacobians) {
    state->pass_at_x.emplace();
    state->pass_at_x->x = polished.x_evaluated;
    state->pass_at_x->normal_equations.resize(p.usable_index.size());
    state->pass_at_x->points.resize(p.usable_index.size());
  }
  size_t j = 0;
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    if (!state->active[k]) continue;
    state->fit_at_x[k] = std::move(polished.fits[j]);
    (*have_fit)[k] = true;
    if (state->pass_at_x) {
      state->pass_at_x->normal_equations[k] = polished.normal_equations[j];
      state->pass_at_x->points[k] = std::move(polished.points[j]);
    }
    ++j;
  }
  std::ostringstream report;
  const auto describe = [&report](const detail::PolishResult& r) {
    report << r.iterations << " iterations, cost " << r.initial_cost << " -> " << r.final_cost
           << (r.converged ? ", converged" : ", hit max_iterations");
  };
  report << "coarse (every " << p.options.coarse_stride << "th point): ";
  describe(coarse);
  report << "; all points: ";
  describe(polished);
  return report.str();
}

/// One round of Eq. (2) on all points of the active views (ours without the coarse stage,
/// or the paper's plane-fit LUT) from *x; returns the solve's report.
std::string solve_all_points(const AlignmentProblem& p, const RoundState& state, core::Vector6d* x,
                             EdgeAlignmentResult* result) {
  const bool paper = p.options.method == EdgeAlignmentMethod::kPaperPlaneFit;
  ceres::Problem problem;
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    if (!state.active[k]) continue;
    const auto& points = p.views[p.usable_index[k]].lidar_circle_points;
    if (paper) {
      for (const auto& point : points) {
        problem.AddResidualBlock(
            new ceres::NumericDiffCostFunction<PaperEdgeResidual, ceres::CENTRAL, 1, 6>(
                new PaperEdgeResidual(&p.cam, p.fields.luts[k].get(), point)),
            nullptr, x->data());
      }
    } else {
      problem.AddResidualBlock(
          new ViewEdgeCost(&p.cam, p.fields.fields[k].get(), &points, p.options.huber_px), nullptr,
          x->data());
    }
  }
  ceres::Solver::Summary summary;
  ceres::Solve(p.solver_options, &problem, &summary);
  result->iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
  result->converged = summary.termination_type == ceres::CONVERGENCE;
  return summary.BriefReport();
}

/// Every usable view's fit at x: its residual in result->views, its sums in *state; returns
/// each view's RMS edge distance.
std::vector<double> measure_view_fits(const AlignmentProblem& p, const std::vector<bool>& have_fit,
                                      const core::Vector6d& x, RoundState* state,
                                      EdgeAlignmentResult* result) {
  std::vector<double> rms(p.usable_index.size(), 0.0);
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    const TargetView& v = p.views[p.usable_index[k]];
    // The polish's last evaluation has the fit of the active views at x; the others (and
    // the paper's method) take one pass here.
    if (!have_fit[k]) {
      state->fit_at_x[k] = fit_of_view(v.lidar_circle_points, *p.fields.fields[k], p.cam,
                                       p.options.huber_px, x, nullptr);
    }
    const detail::PointFit& fit = state->fit_at_x[k];
    double sum2 = 0.0;
    for (double d : fit.distances_px) sum2 += d * d;
    state->sum2_of_view[k] = sum2;
    state->count_of_view[k] = fit.distances_px.size();
    rms[k] = std::sqrt(sum2 / std::max<size_t>(1, fit.distances_px.size()));
    ViewResidual& vr = result->views[p.usable_index[k]];
    vr.rms_px = rms[k];
    vr.median_px = median_of(fit.distances_px);
    vr.num_in_image = fit.in_image;
  }
  return rms;
}

/// The active view that fits worst beyond the limits (index into usable_index, -1 if none).
struct WorstView {
  int index = -1;
  std::string reason;
};

WorstView find_worst_view(const AlignmentProblem& p, const RoundState& state,
                          const std::vector<double>& rms, const EdgeAlignmentResult& result) {
  const EdgeAlignmentOptions& options = p.options;
  std::vector<double> active_rms;
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    if (state.active[k]) active_rms.push_back(rms[k]);
  }
  const double median_rms = median_of(active_rms);
  const double limit = std::max(options.outlier_min_rms_px, options.outlier_rms_ratio * median_rms);
  WorstView worst;
  double worst_score = 0.0;
  for (size_t k = 0; k < p.usable_index.size(); ++k) {
    if (!state.active[k]) continue;
    const ViewResidual& vr = result.views[p.usable_index[k]];
    const double in_fraction = vr.num_points ? double(vr.num_in_image) / vr.num_points : 0.0;
    std::ostringstream why;
    double score = 0.0;
    if (in_fraction < options.min_in_image_fraction) {
      why << "only " << vr.num_in_image << " of " << vr.num_points
          << " LIDAR circle points project into the image at the solution";
      score = std::numeric_limits<double>::max();
    } else if (rms[k] > limit) {
      why.precision(3);
      why << "RMS edge distance " << rms[k] << " px exceeds " << limit
          << " px (max of outlier_min_rms_px and " << options.outlier_rms_ratio << " x median "
          << median_rms << " px): its image edges do not match its LIDAR circle";
      score = rms[k] / limit;
    }
    if (score > worst_score) {
      worst_score = score;
      worst.index = static_cast<int>(k);
      worst.reason = why.str();
    }
  }
  return worst;
}

/// Takes the worst view out of the solve and records why; false (and the reason in
/// *message) when it is the only active view left.
bool reject_view(const WorstView& worst, const std::vector<size_t>& usable_index, RoundState* state,
                 EdgeAlignmentResult* result, std::ostringstream* message) {
  const long n_active = std::count(state->active.begin(), state->active.end(), true);
  if (n_active <= 1) {
    *message << "the only remaining view is poor (" << worst.reason << "); ";
    return false;
  }
  state->active[worst.index] = false;
  ViewResidual& vr = result->views[usable_index[worst.index]];
  vr.used = false;
  vr.reason = worst.reason;
  core::log_warning("extrinsics: rejected ", vr.name, ": ", worst.reason);
  *message << "rejected " << vr.name << "; ";
  return true;
}

/// result->rms_px over the active views' points (the fit of the last round, at the
/// solution); returns their count.
size_t set_overall_rms(const RoundState& state, EdgeAlignmentResult* result) {
  double sum2 = 0.0;
  size_t count = 0;
  for (size_t k = 0; k < state.active.size(); ++k) {
    if (!state.active[k]) continue;
    sum2 += state.sum2_of_view[k];  // the fit of the last round, at this x
    count += state.count_of_view[k];
  }
  result->rms_px = count ? std::sqrt(sum2 / count) : 0.0;
  return count;
}

/// at_x: the solve's last pass at x, or null.
void set_covariance(const AlignmentProblem& p, const RoundState& state, const core::Vector6d& x,
                    const PassAtSolution* at_x, EdgeAlignmentResult* result, std::ostringstream* message) {
  result->covariance_terms = covariance_at_solution(p.views, p.usable_index, state.active,
                                                    p.fields.fields, p.cam, x, p.options, at_x);
  result->covariance = result->covariance_terms.total;
  result->covariance_valid = result->covariance_terms.valid;
  if (!result->covariance_valid) {
    *message << "covariance rank-deficient (a direction is unobservable); ";
  }
}

}  // namespace

std::string to_string(EdgeAlignmentMethod method) {
  return method == EdgeAlignmentMethod::kPaperPlaneFit ? "paper" : "edge";
}

EdgeAlignmentMethod edge_alignment_method_from_string(const std::string& name) {
  if (name == "edge") return EdgeAlignmentMethod::kSmoothField;
  if (name == "paper") return EdgeAlignmentMethod::kPaperPlaneFit;
  throw std::invalid_argument("edge alignment method '" + name +
                              "' is unknown (expected 'edge' or 'paper')");
}

std::string EdgeAlignmentOptions::validate() const {
  std::ostringstream os;
  if (!(huber_px >= 0.0)) os << "huber_px = " << huber_px << ", expected >= 0; ";
  if (max_iterations < 1) os << "max_iterations = " << max_iterations << ", expected >= 1; ";
  if (!(function_tolerance > 0.0)) os << "function_tolerance must be > 0; ";
  if (!(parameter_tolerance > 0.0)) os << "parameter_tolerance must be > 0; ";
  if (!(step_tolerance_sigma >= 0.0))
    os << "step_tolerance_sigma = " << step_tolerance_sigma << ", expected >= 0; ";
  if (paper_window_px < 2) os << "paper_window_px = " << paper_window_px << ", expected >= 2; ";
  if (!(outlier_rms_ratio > 1.0))
    os << "outlier_rms_ratio = " << outlier_rms_ratio << ", expected > 1; ";
  if (!(outlier_min_rms_px > 0.0))
    os << "outlier_min_rms_px = " << outlier_min_rms_px << ", expected > 0; ";
  if (!(min_in_image_fraction >= 0.0 && min_in_image_fraction <= 1.0))
    os << "min_in_image_fraction = " << min_in_image_fraction << ", expected in [0, 1]; ";
  if (coarse_stride < 1) os << "coarse_stride = " << coarse_stride << ", expected >= 1; ";
  os << field.validate();
  if (const std::string why = covariance_model.validate(); !why.empty())
    os << "covariance_model: " << why << "; ";
  return os.str();
}

std::vector<int> EdgeAlignmentResult::outlier_views() const {
  std::vector<int> out;
  for (size_t i = 0; i < views.size(); ++i)
    if (!views[i].used) out.push_back(static_cast<int>(i));
  return out;
}

EdgeAlignmentResult align_edges(const std::vector<TargetView>& views,
                                const core::PinholeCamera& camera,
                                const EdgeAlignmentOptions& options,
                                std::optional<Eigen::Isometry3d> T_camera_lidar_guess) {
  const auto t_start = std::chrono::steady_clock::now();
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("align_edges: invalid options: " + why);
  }
  EdgeAlignmentResult result;
  EdgeAlignmentResult::StageTimes& times = result.stage_times;
  const std::vector<size_t> usable_index = label_views(views, camera, &result);
  auto t0 = std::chrono::steady_clock::now();
  set_initial_pose(views, usable_index, camera, T_camera_lidar_guess, &result);
  times.initial_guess_s = seconds_since(t0);

  const ProjectionModel cam = detail::make_projection_model(camera);
  const bool paper = options.method == EdgeAlignmentMethod::kPaperPlaneFit;
  t0 = std::chrono::steady_clock::now();
  const ViewFields fields = build_view_fields(views, usable_index, camera, options, &times.paper_luts_s);
  times.fields_s = seconds_since(t0) - times.paper_luts_s;
  t0 = std::chrono::steady_clock::now();
  core::Vector6d x = core::to_vector6(result.T_camera_lidar_initial);
  if (options.coarse_center_stage && !paper) {
    result.iterations += align_hole_centers(views, usable_index, cam, &x);
  }

  const ceres::Solver::Options solver_options = edge_solver_options(options);
  const AlignmentProblem problem{views, usable_index, cam, fields, options, solver_options};
  // Eq. (2) on the coarse subset brings the pose near the minimum at a fraction of the
  // cost per iteration; the full set then only has to polish it (a few iterations).
  const bool coarse_first = !paper && options.coarse_stride > 1;
  RoundState state(usable_index.size());
  std::string polish_report;
  std::ostringstream message;
  for (int round = 0;; ++round) {
    std::vector<bool> have_fit(usable_index.size(), false);
    polish_report = coarse_first ? solve_coarse_then_polish(problem, &state, &have_fit, &x, &result)
                                 : solve_all_points(problem, state, &x, &result);
    // Per-view fit at this solution; reject the worst outlier view, if any, and re-solve.
    const std::vector<double> rms = measure_view_fits(problem, have_fit, x, &state, &result);
    if (!options.reject_outlier_views) break;
    const WorstView worst = find_worst_view(problem, state, rms, result);
    if (worst.index < 0) break;
    if (!reject_view(worst, usable_index, &state, &result, &message)) break;
    if (round > static_cast<int>(usable_index.size())) break;
  }

  result.T_camera_lidar = core::from_vector6(x);
  // The covariance belongs to the rotation vector the YAML writes (to_vector6, angle <= pi).
  // A solve near a half turn can end past pi, in the other chart, where the directions across
  // the axis point the opposite way: the covariance would pair rotation and translation
  // with the wrong signs. In the same chart (the round trip differs by rounding) the solve's
  // last pass at x is the covariance's.
  const auto in_written_chart = [](const core::Vector6d& v) {
    return (core::to_vector6(core::from_vector6(v)) - v).norm() <= 1e-9 * (1.0 + v.norm());
  };
  const bool same_chart = in_written_chart(x) && (!state.pass_at_x || in_written_chart(state.pass_at_x->x));
  if (!same_chart) x = core::to_vector6(result.T_camera_lidar);
  const size_t count = set_overall_rms(state, &result);
  times.alignment_s = seconds_since(t0);
  if (options.compute_covariance && count > 6) {
    t0 = std::chrono::steady_clock::now();
    const PassAtSolution* at_x = same_chart && state.pass_at_x ? &*state.pass_at_x : nullptr;
    set_covariance(problem, state, x, at_x, &result, &message);
    times.covariance_s = seconds_since(t0);
  }

  message << (paper ? "paper plane-fit LUT" : "smooth field") << ", " << polish_report;
  result.message = message.str();
  result.solve_time_s = seconds_since(t_start);
  return result;
}

std::vector<double> point_to_edge_distances(const TargetView& view,
                                            const core::PinholeCamera& camera,
                                            const Eigen::Isometry3d& T_camera_lidar) {
  const SmoothView field(view.image_edge_points_px, {});
  const ProjectionModel cam = detail::make_projection_model(camera);
  return fit_of_view(view.lidar_circle_points, field, cam, 0.0, core::to_vector6(T_camera_lidar), nullptr)
      .distances_px;
}

}  // namespace rgbdt::extrinsics
