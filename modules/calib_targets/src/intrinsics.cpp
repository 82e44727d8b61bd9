#include "rgbdt/calib_targets/intrinsics.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "rgbdt/calib_targets/image_target.hpp"

namespace rgbdt::calib_targets {

namespace {

using core::DistortionModel;

struct Model {
  std::string terms;
  int flags = 0;
  std::vector<int> free;  ///< indices of estimated coefficients in the distortion vector
};

std::vector<Model> candidate_models(DistortionModel model, bool select) {
  if (model == DistortionModel::kEquidistant) {
    const int base = cv::fisheye::CALIB_RECOMPUTE_EXTRINSIC | cv::fisheye::CALIB_FIX_SKEW;
    std::vector<Model> all = {
        {"k1 k2", base | cv::fisheye::CALIB_FIX_K3 | cv::fisheye::CALIB_FIX_K4, {0, 1}},
        {"k1 k2 k3", base | cv::fisheye::CALIB_FIX_K4, {0, 1, 2}},
        {"k1 k2 k3 k4", base, {0, 1, 2, 3}}};
    return select ? all : std::vector<Model>{all.back()};
  }
  std::vector<Model> all = {
      {"k1 k2", cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K3, {0, 1}},
      {"k1 k2 p1 p2", cv::CALIB_FIX_K3, {0, 1, 2, 3}},
      {"k1 k2 k3", cv::CALIB_ZERO_TANGENT_DIST, {0, 1, 4}},
      {"k1 k2 p1 p2 k3", 0, {0, 1, 2, 3, 4}}};
  return select ? all : std::vector<Model>{all.back()};
}

struct Fit {
  bool ok = false;
  cv::Mat K, D;
  std::vector<cv::Mat> rvecs, tvecs;
  double rms = 0.0;
  cv::Mat std_intrinsics;  ///< plumb_bob only (OpenCV)
};

Fit fit(DistortionModel model, const Model& m, const std::vector<std::vector<cv::Point3f>>& obj,
        const std::vector<std::vector<cv::Point2f>>& img, cv::Size size) {
  Fit f;
  try {
    if (model == DistortionModel::kEquidistant) {
      std::vector<std::vector<cv::Point3d>> o(obj.size());
      std::vector<std::vector<cv::Point2d>> i(img.size());
      for (std::size_t v = 0; v < obj.size(); ++v) {
        for (const auto& p : obj[v]) o[v].emplace_back(p.x, p.y, p.z);
        for (const auto& p : img[v]) i[v].emplace_back(p.x, p.y);
      }
      f.K = cv::Mat::eye(3, 3, CV_64F);
      f.D = cv::Mat::zeros(4, 1, CV_64F);
      f.rms = cv::fisheye::calibrate(o, i, size, f.K, f.D, f.rvecs, f.tvecs, m.flags,
                                     cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-10));
    } else {
      cv::Mat std_ext, per_view;
      f.rms = cv::calibrateCamera(obj, img, size, f.K, f.D, f.rvecs, f.tvecs, f.std_intrinsics, std_ext,
                                  per_view, m.flags,
                                  cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
      f.D = f.D.reshape(1, static_cast<int>(f.D.total()));
      if (f.D.rows > 5) f.D = f.D.rowRange(0, 5).clone();
    }
    f.ok = std::isfinite(f.rms);
  } catch (const cv::Exception&) {
    f.ok = false;
  }
  return f;
}

std::vector<cv::Point2f> project(DistortionModel model, const std::vector<cv::Point3f>& obj,
                                 const cv::Mat& rvec, const cv::Mat& tvec, const cv::Mat& K, const cv::Mat& D) {
  std::vector<cv::Point2f> out;
  if (model == DistortionModel::kEquidistant) {
    std::vector<cv::Point3d> o;
    for (const auto& p : obj) o.emplace_back(p.x, p.y, p.z);
    std::vector<cv::Point2d> px;
    cv::fisheye::projectPoints(o, px, rvec, tvec, K, D);
    for (const auto& p : px) out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  } else {
    cv::projectPoints(obj, rvec, tvec, K, D, out);
  }
  return out;
}

double rms_of(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b) {
  double s = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double dx = a[k].x - b[k].x, dy = a[k].y - b[k].y;
    s += dx * dx + dy * dy;
  }
  return a.empty() ? 0.0 : std::sqrt(s / static_cast<double>(a.size()));
}

/// Held-out reprojection RMS of a view posed with solvePnP under given intrinsics.
double heldout_rms(DistortionModel model, const std::vector<cv::Point3f>& obj,
                   const std::vector<cv::Point2f>& img, const cv::Mat& K, const cv::Mat& D) {
  cv::Mat rvec, tvec;
  if (model == DistortionModel::kEquidistant) {
    std::vector<cv::Point2f> und;
    cv::fisheye::undistortPoints(img, und, K, D);
    cv::solvePnP(obj, und, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec);
  } else {
    cv::solvePnP(obj, img, K, D, rvec, tvec);
  }
  // Refine the pose on the full model (solvePnP's LM on plumb_bob is exact already).
  return rms_of(project(model, obj, rvec, tvec, K, D), img);
}

/// 1-sigma of the intrinsics from the Gauss-Newton normal matrix (numeric Jacobian over
/// intrinsics and all poses), scaled by the residual variance. Used for the equidistant
/// model, for which OpenCV reports none.
std::vector<double> numeric_std(DistortionModel model, const Model& m, const Fit& f,
                                const std::vector<std::vector<cv::Point3f>>& obj,
                                const std::vector<std::vector<cv::Point2f>>& img) {
  const int ni = 4 + static_cast<int>(m.free.size());
  const int nv = static_cast<int>(obj.size());
  const int np = ni + 6 * nv;
  int nr = 0;
  for (const auto& o : obj) nr += 2 * static_cast<int>(o.size());
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(nr, np);
  Eigen::VectorXd r0(nr);
  auto residuals_view = [&](int v, const cv::Mat& K, const cv::Mat& D, const cv::Mat& rv, const cv::Mat& tv) {
    return project(model, obj[static_cast<std::size_t>(v)], rv, tv, K, D);
  };
  std::vector<int> offset(static_cast<std::size_t>(nv) + 1, 0);
  for (int v = 0; v < nv; ++v) offset[static_cast<std::size_t>(v) + 1] = offset[static_cast<std::size_t>(v)] + 2 * static_cast<int>(obj[static_cast<std::size_t>(v)].size());
  double rss = 0.0;
  for (int v = 0; v < nv; ++v) {
    const auto p = residuals_view(v, f.K, f.D, f.rvecs[static_cast<std::size_t>(v)], f.tvecs[static_cast<std::size_t>(v)]);
    for (std::size_t k = 0; k < p.size(); ++k) {
      const double dx = p[k].x - img[static_cast<std::size_t>(v)][k].x, dy = p[k].y - img[static_cast<std::size_t>(v)][k].y;
      rss += dx * dx + dy * dy;
    }
  }
  auto column = [&](int v, const std::vector<cv::Point2f>& plus, const std::vector<cv::Point2f>& minus, double h, int c) {
    for (std::size_t k = 0; k < plus.size(); ++k) {
      J(offset[static_cast<std::size_t>(v)] + 2 * static_cast<int>(k), c) = (plus[k].x - minus[k].x) / (2 * h);
      J(offset[static_cast<std::size_t>(v)] + 2 * static_cast<int>(k) + 1, c) = (plus[k].y - minus[k].y) / (2 * h);
    }
  };
  for (int c = 0; c < ni; ++c) {
    cv::Mat Kp = f.K.clone(), Km = f.K.clone(), Dp = f.D.clone(), Dm = f.D.clone();
    double h = 0.0;
    if (c < 4) {
      const int rr = c == 0 ? 0 : c == 1 ? 1 : c == 2 ? 0 : 1;
      const int cc = c == 0 ? 0 : c == 1 ? 1 : 2;
      h = 1e-3 * std::max(1.0, std::abs(f.K.at<double>(rr, cc)));
      Kp.at<double>(rr, cc) += h;
      Km.at<double>(rr, cc) -= h;
    } else {
      const int d = m.free[static_cast<std::size_t>(c - 4)];
      h = 1e-6;
      Dp.at<double>(d) += h;
      Dm.at<double>(d) -= h;
    }
    for (int v = 0; v < nv; ++v) {
      column(v, residuals_view(v, Kp, Dp, f.rvecs[static_cast<std::size_t>(v)], f.tvecs[static_cast<std::size_t>(v)]),
             residuals_view(v, Km, Dm, f.rvecs[static_cast<std::size_t>(v)], f.tvecs[static_cast<std::size_t>(v)]), h, c);
    }
  }
  for (int v = 0; v < nv; ++v) {
    for (int q = 0; q < 6; ++q) {
      cv::Mat rp = f.rvecs[static_cast<std::size_t>(v)].clone(), rm = rp.clone();
      cv::Mat tp = f.tvecs[static_cast<std::size_t>(v)].clone(), tm = tp.clone();
      rp.convertTo(rp, CV_64F);
      rm.convertTo(rm, CV_64F);
      tp.convertTo(tp, CV_64F);
      tm.convertTo(tm, CV_64F);
      const double h = 1e-6;
      if (q < 3) {
        rp.at<double>(q) += h;
        rm.at<double>(q) -= h;
      } else {
        tp.at<double>(q - 3) += h;
        tm.at<double>(q - 3) -= h;
      }
      column(v, residuals_view(v, f.K, f.D, rp, tp), residuals_view(v, f.K, f.D, rm, tm), h, ni + 6 * v + q);
    }
  }
  const double sigma2 = rss / std::max(1, nr - np);
  const Eigen::MatrixXd cov = (J.transpose() * J).ldlt().solve(Eigen::MatrixXd::Identity(np, np)) * sigma2;
  std::vector<double> out;
  for (int c = 0; c < ni; ++c) out.push_back(std::sqrt(std::max(0.0, cov(c, c))));
  return out;
}

}  // namespace

PatternType pattern_type_from_string(const std::string& name) {
  if (name == "checkerboard" || name == "chessboard") return PatternType::kCheckerboard;
  if (name == "circles") return PatternType::kCircles;
  if (name == "acircles") return PatternType::kAsymmetricCircles;
  throw std::invalid_argument("pattern '" + name + "': expected checkerboard, circles or acircles");
}

std::string to_string(PatternType type) {
  switch (type) {
    case PatternType::kCheckerboard: return "checkerboard";
    case PatternType::kCircles: return "circles";
    case PatternType::kAsymmetricCircles: return "acircles";
  }
  return "checkerboard";
}

std::string PatternSpec::validate() const {
  std::ostringstream s;
  if (cols < 2 || rows < 2) s << "pattern size " << cols << "x" << rows << " must be at least 2x2; ";
  if (!(spacing_m > 0)) s << "spacing_m = " << spacing_m << " must be > 0; ";
  return s.str();
}

std::vector<cv::Point3f> PatternSpec::object_points() const {
  std::vector<cv::Point3f> out;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      if (type == PatternType::kAsymmetricCircles) {
        // OpenCV's asymmetric grid: spacing is the distance between neighbours in a row/2.
        out.emplace_back(static_cast<float>((2 * c + r % 2) * spacing_m), static_cast<float>(r * spacing_m), 0.f);
      } else {
        out.emplace_back(static_cast<float>(c * spacing_m), static_cast<float>(r * spacing_m), 0.f);
      }
    }
  }
  return out;
}

std::string PatternDetectionOptions::validate() const {
  std::ostringstream s;
  if (!(low_percentile >= 0 && high_percentile <= 100 && low_percentile < high_percentile)) s << "percentiles must satisfy 0 <= low < high <= 100; ";
  if (subpix_window_px < 1) s << "subpix_window_px must be >= 1; ";
  return s.str();
}

std::string IntrinsicsOptions::validate() const {
  std::ostringstream s;
  if (model != DistortionModel::kPlumbBob && model != DistortionModel::kEquidistant) s << "model must be plumb_bob or equidistant; ";
  if (folds < 2) s << "folds = " << folds << " must be >= 2; ";
  if (!(outlier_factor > 1)) s << "outlier_factor must be > 1; ";
  if (!(max_view_rms_px > 0)) s << "max_view_rms_px must be > 0; ";
  if (min_views < 3) s << "min_views must be >= 3; ";
  return s.str();
}

namespace {

/// The refinement of sector-based corners is kept when cornerSubPix moves 90 % of them by at
/// most this [px]: a few times SB's own localisation error (~0.15 px on sharp corners).
/// Measured: simulated thermal boards 0.09-0.33 px; blurred real ones (czha626) 1.5-5 px.
constexpr double kRefinementAgreementPx = 0.75;

/// The detectors search images of at most this size [px] (larger ones are downscaled).
constexpr int kSearchWidthPx = 1000;
/// The 2x upscaled attempt (small patterns) only for images whose copy stays this small.
constexpr int kMaxUpscaledWidthPx = 1400;

/// Mean of the normalised image over a small square around a point (clamped to the image).
double patch_mean(const cv::Mat& f, cv::Point2f c, int half) {
  const int x0 = std::clamp(static_cast<int>(std::lround(c.x)) - half, 0, f.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::lround(c.y)) - half, 0, f.rows - 1);
  const int x1 = std::clamp(static_cast<int>(std::lround(c.x)) + half, 0, f.cols - 1);
  const int y1 = std::clamp(static_cast<int>(std::lround(c.y)) + half, 0, f.rows - 1);
  return cv::mean(f(cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1)))[0];
}

/// Every detected corner must be a checkerboard saddle: of the four squares around it (sampled
/// half a grid step along both grid directions), the two on one diagonal alike, the two on the
/// other alike, and the diagonals far apart. The sector-based detector can otherwise accept a
/// grid shifted by one row onto the board's edge (uniform or masked background beyond it,
/// seen on the czha626 masked thermal images), every "corner" of that row sitting on a
/// straight edge. Returns an empty string or why the detection is rejected.
std::string checkerboard_saddle_problem(const cv::Mat& f, const std::vector<cv::Point2f>& pts, cv::Size size) {
  const int cols = size.width, rows = size.height;
  const auto at = [&](int r, int c) { return pts[static_cast<std::size_t>(r * cols + c)]; };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const cv::Point2f p = at(r, c);
      const cv::Point2f u = c + 1 < cols ? at(r, c + 1) - p : p - at(r, c - 1);
      const cv::Point2f v = r + 1 < rows ? at(r + 1, c) - p : p - at(r - 1, c);
      const double step = std::min(std::hypot(u.x, u.y), std::hypot(v.x, v.y));
      // Sample well inside each square (a third of the way to its far corner), over a patch a
      // sixth of a square wide, so blur at the square's edges does not matter.
      const int half = std::max(1, static_cast<int>(step / 12.0));
      const double pp = patch_mean(f, p + (u + v) * (1.0f / 3.0f), half);
      const double mm = patch_mean(f, p - (u + v) * (1.0f / 3.0f), half);
      const double pm = patch_mean(f, p + (u - v) * (1.0f / 3.0f), half);
      const double mp = patch_mean(f, p - (u - v) * (1.0f / 3.0f), half);
      const double contrast = std::abs(0.5 * (pp + mm) - 0.5 * (pm + mp));
      // Normalised image: squares span most of [0, 1]. A real corner has a contrast of a large
      // part of that and like squares within half of it; an edge "corner" has one diagonal
      // pairing a square with background.
      if (contrast < 0.15 || std::abs(pp - mm) > 0.5 * contrast || std::abs(pm - mp) > 0.5 * contrast) {
        std::ostringstream os;
        os.precision(3);
        os << "corner (" << r << ", " << c << ") at (" << p.x << ", " << p.y
           << ") px is not a checkerboard saddle (squares around it " << pp << " " << mm << " / " << pm << " "
           << mp << ")";
        return os.str();
      }
    }
  }
  return {};
}

/// One image the detectors search: the normalised 8-bit image, maybe downscaled, upscaled,
/// equalised or inverted.
struct Variant {
  cv::Mat img;
  bool inverted;
  double scale;
  std::string name;
};

std::vector<Variant> image_variants(const cv::Mat& u8, const PatternDetectionOptions& options) {
  // The search runs on images of at most kSearchWidthPx (a larger image is downscaled; its
  // corners are refined at full resolution afterwards): the detectors' cost grows much
  // faster than the pixel count (findChessboardCorners on a 1288x964 image without a
  // pattern: 100 s, on a 1000 px wide copy: 0.5 s).
  const double search_scale = std::min(1.0, kSearchWidthPx / static_cast<double>(std::max(u8.cols, u8.rows)));
  cv::Mat search = u8;
  std::string scale_name;
  if (search_scale < 1.0) {
    cv::resize(u8, search, cv::Size(), search_scale, search_scale, cv::INTER_AREA);
    std::ostringstream os;
    os.precision(2);
    os << " " << search_scale << "x";
    scale_name = os.str();
  }
  std::vector<Variant> variants = {{search, false, search_scale, "normalised" + scale_name}};
  if (options.try_inverted) variants.push_back({255 - search, true, search_scale, "normalised inverted" + scale_name});
  if (options.try_clahe) {
    cv::Mat c;
    cv::createCLAHE(3.0, cv::Size(8, 8))->apply(search, c);
    variants.push_back({c, false, search_scale, "CLAHE" + scale_name});
    if (options.try_inverted) variants.push_back({255 - c, true, search_scale, "CLAHE inverted" + scale_name});
  }
  // Small images only (thermal cameras): the 2x copy stays within kMaxUpscaledWidthPx.
  if (options.try_upscale && 2 * std::max(u8.cols, u8.rows) <= kMaxUpscaledWidthPx) {
    cv::Mat up;
    cv::resize(u8, up, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
    variants.push_back({up, false, 2.0, "normalised 2x"});
    if (options.try_inverted) variants.push_back({255 - up, true, 2.0, "normalised inverted 2x"});
  }
  return variants;
}

/// A variant and the detector mode to run on it.
using Attempt = std::pair<const Variant*, int>;

/// Cheapest attempts first: every variant with the default detectors, then the
/// exhaustive sector-based search on the normalised image only.
/// Attempts: (variant, mode) with mode 0 = sector-based detector (SB), 3 = SB without its
/// own histogram equalisation (CALIB_CB_NORMALIZE_IMAGE amplifies the noise of a large
/// uniform background until a small board is lost: 3 of 6 simulated RGB board images),
/// 1 = SB exhaustive, 2 = classic quad detector (its corners are less accurate, so it
/// comes last; with CALIB_CB_FAST_CHECK, and only on images that were not downscaled:
/// on a 1000 px copy of an RGB board image it still runs 4-10 s per variant).
/// *plausible: whether the image may show the pattern (always for circle grids).
std::vector<Attempt> detection_attempts(const std::vector<Variant>& variants,
                                        const PatternSpec& pattern, cv::Size size,
                                        bool* plausible) {
  std::vector<Attempt> attempts;
  for (const Variant& v : variants) attempts.emplace_back(&v, 0);
  // cv::checkChessboard (the quick test behind CALIB_CB_FAST_CHECK: a few ms to 0.25 s per
  // variant) decides whether the search is worth it. Where no variant passes it, only the
  // first attempt runs. Measured (shared data: czha626 raw and masked, 94 real thermal
  // images; 60 simulated thermal and 20 RGB board images): every image whose board the
  // search finds passes on at least one variant; the 20 simulated night images, whose board
  // no attempt finds, and uniform noise pass on none. A 640x512 image without the pattern
  // then ends after about 1 s instead of 11.6 s.
  *plausible = pattern.type != PatternType::kCheckerboard;
  for (const Variant& v : variants) *plausible = *plausible || cv::checkChessboard(v.img, size);
  if (!*plausible) attempts.resize(1);
  if (*plausible && pattern.type == PatternType::kCheckerboard) {
    for (const Variant& v : variants) attempts.emplace_back(&v, 3);
    attempts.emplace_back(&variants[0], 1);
    for (const Variant& v : variants)
      if (v.scale >= 1.0 && std::max(v.img.cols, v.img.rows) <= kMaxUpscaledWidthPx) attempts.emplace_back(&v, 2);
  }
  return attempts;
}

/// Runs one attempt's detector on the variant: whether it found the pattern, its points in
/// the variant's pixels and the detector's name.
bool run_detector(const Variant& v, int mode, const PatternSpec& pattern, cv::Size size,
                  std::vector<cv::Point2f>* pts, std::string* method) {
  const bool exhaustive = mode == 1;
  bool found = false;
  if (pattern.type == PatternType::kCheckerboard) {
    if (mode != 2) {
      // CALIB_CB_ACCURACY only where the corners are final: a downscaled copy's are
      // refined at full resolution below.
      const int sb_flags = (mode == 3 ? 0 : cv::CALIB_CB_NORMALIZE_IMAGE) |
                           (v.scale >= 1.0 ? cv::CALIB_CB_ACCURACY : 0) |
                           (exhaustive ? cv::CALIB_CB_EXHAUSTIVE : 0);
      found = cv::findChessboardCornersSB(v.img, size, *pts, sb_flags);
      *method = exhaustive  ? "findChessboardCornersSB (exhaustive)"
                : mode == 3 ? "findChessboardCornersSB (no equalisation)"
                            : "findChessboardCornersSB";
    } else {
      found =
          cv::findChessboardCorners(v.img, size, *pts,
                                    cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE |
                                        cv::CALIB_CB_FILTER_QUADS | cv::CALIB_CB_FAST_CHECK);
      *method = "findChessboardCorners";
    }
    return found;
  }
  cv::SimpleBlobDetector::Params p;
  p.filterByColor = true;
  p.blobColor = v.inverted ? 255 : 0;
  p.minArea = 8.0f * static_cast<float>(v.scale * v.scale);
  p.maxArea = static_cast<float>(0.05 * static_cast<double>(v.img.total()));
  p.filterByCircularity = true;
  p.minCircularity = 0.5f;
  p.filterByInertia = true;
  p.minInertiaRatio = 0.1f;
  p.filterByConvexity = true;
  p.minConvexity = 0.8f;
  auto blob = cv::SimpleBlobDetector::create(p);
  const int grid = pattern.type == PatternType::kCircles ? cv::CALIB_CB_SYMMETRIC_GRID
                                                         : cv::CALIB_CB_ASYMMETRIC_GRID;
  found = cv::findCirclesGrid(v.img, size, *pts, grid, blob);
  *method = "findCirclesGrid";
  if (!found) {
    found = cv::findCirclesGrid(v.img, size, *pts, grid | cv::CALIB_CB_CLUSTERING, blob);
    *method = "findCirclesGrid (clustering)";
  }
  return found;
}

/// A variant's points in the full-resolution image.
void to_full_resolution(double scale, std::vector<cv::Point2f>* pts) {
  for (auto& p : *pts) p *= static_cast<float>(1.0 / scale);
  if (scale != 1.0) {
    // Keep the sub-pixel offset of the centre convention: (x + 0.5) / s - 0.5.
    for (auto& p : *pts)
      p +=
          cv::Point2f(static_cast<float>(0.5 / scale - 0.5), static_cast<float>(0.5 / scale - 0.5));
  }
}

/// Refine on the original data (normalised float, no 8-bit quantisation). The sector-based
/// detector with CALIB_CB_ACCURACY already localises corners to ~0.1 px; cornerSubPix is
/// finer on sharp X-junctions (simulated thermal boards: 0.04 px vs 0.12 px RMS) but
/// wanders off on blurred real ones with rounded squares (czha626 masked set, 39 views:
/// SB alone 0.56 px RMS, SB corners moved 1.5-3 px by an 11x11 cornerSubPix, 2.2 px RMS).
/// So the refinement is kept only where both estimators agree to within SB's precision;
/// the classic detector's corners are always refined. *method notes corners kept.
void refine_checkerboard_corners(const cv::Mat& f, const Variant& v, int mode,
                                 const PatternDetectionOptions& options,
                                 std::vector<cv::Point2f>* pts, std::string* method) {
  std::vector<cv::Point2f> refined = *pts;
  cv::cornerSubPix(f, refined, cv::Size(options.subpix_window_px, options.subpix_window_px),
                   cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
  std::vector<double> moves;
  for (std::size_t k = 0; k < pts->size(); ++k) moves.push_back(cv::norm(refined[k] - (*pts)[k]));
  std::sort(moves.begin(), moves.end());
  const double p90_move = moves[moves.size() * 9 / 10];
  // A downscaled detection's corners are only as precise as its pixels are large.
  if (mode == 2 || p90_move <= kRefinementAgreementPx / std::min(1.0, v.scale)) {
    *pts = refined;
  } else {
    std::ostringstream os;
    os.precision(2);
    os << " (SB corners kept: cornerSubPix moved 10 % of them > " << p90_move << " px)";
    *method += os.str();
  }
}

}  // namespace

PatternDetection detect_pattern(const cv::Mat& image, const PatternSpec& pattern,
                                const PatternDetectionOptions& options) {
  if (const std::string e = pattern.validate() + options.validate(); !e.empty())
    throw std::invalid_argument(e);
  PatternDetection det;
  if (image.empty()) {
    det.reason = "empty image";
    return det;
  }
  const cv::Mat f = normalise_image(image, options.low_percentile, options.high_percentile);
  cv::Mat u8;
  f.convertTo(u8, CV_8U, 255.0);
  const cv::Size size(pattern.cols, pattern.rows);
  const std::vector<Variant> variants = image_variants(u8, options);
  bool plausible = false;
  const std::vector<Attempt> attempts = detection_attempts(variants, pattern, size, &plausible);
  std::string rejected;  // the last detection that failed the saddle check
  for (const auto& [vp, mode] : attempts) {
    const Variant& v = *vp;
    std::vector<cv::Point2f> pts;
    std::string method;
    if (!run_detector(v, mode, pattern, size, &pts, &method)) continue;
    if (pts.size() != static_cast<std::size_t>(pattern.cols * pattern.rows)) continue;
    to_full_resolution(v.scale, &pts);
    if (pattern.type == PatternType::kCheckerboard) {
      refine_checkerboard_corners(f, v, mode, options, &pts, &method);
      if (const std::string why = checkerboard_saddle_problem(f, pts, size); !why.empty()) {
        rejected = method + " on " + v.name + ": " + why;
        continue;  // a false grid; the next detector or variant may find the real one
      }
    }
    det.ok = true;
    det.points = pts;
    det.inverted = v.inverted;
    det.method = method + " on " + v.name;
    return det;
  }
  det.reason = "pattern " + std::to_string(pattern.cols) + "x" + std::to_string(pattern.rows) + " " +
               to_string(pattern.type) +
               (plausible ? " not found in either polarity"
                          : " not found: no image variant looks like a checkerboard (cv::checkChessboard), and "
                            "findChessboardCornersSB on the normalised image found none");
  if (!rejected.empty()) det.reason += " (rejected " + rejected + ")";
  return det;
}

namespace {

/// Fills res->views with each view's name, points and, when it has no detection, the reason;
/// returns the indices of the detected views.
std::vector<std::size_t> label_views(const std::vector<PatternDetection>& detections,
                                     const std::vector<std::string>& names, IntrinsicsResult* res) {
  res->views.resize(detections.size());
  std::vector<std::size_t> used;
  for (std::size_t v = 0; v < detections.size(); ++v) {
    res->views[v].name = names[v];
    res->views[v].points = detections[v].points;
    if (detections[v].ok) {
      used.push_back(v);
    } else {
      res->views[v].reason = detections[v].reason;
    }
  }
  return used;
}

/// The board and detected points of the views `which`, one entry per view.
void gather(const std::vector<cv::Point3f>& board, const std::vector<PatternDetection>& detections,
            const std::vector<std::size_t>& which, std::vector<std::vector<cv::Point3f>>* o,
            std::vector<std::vector<cv::Point2f>>* i) {
  o->clear();
  i->clear();
  for (std::size_t v : which) {
    o->push_back(board);
    i->push_back(detections[v].points);
  }
}

/// Outlier views: calibrate with the fullest model, reject views far above the median (up
/// to three rounds; the reason in res->views). Returns the views kept.
std::vector<std::size_t> reject_outlier_views(const std::vector<PatternDetection>& detections,
                                              std::vector<std::size_t> used, cv::Size image_size,
                                              const std::vector<cv::Point3f>& board,
                                              const Model& fullest,
                                              const IntrinsicsOptions& options,
                                              IntrinsicsResult* res) {
  std::vector<std::vector<cv::Point3f>> obj;
  std::vector<std::vector<cv::Point2f>> img;
  for (int round = 0; round < 3; ++round) {
    if (static_cast<int>(used.size()) < options.min_views) break;
    gather(board, detections, used, &obj, &img);
    const Fit f = fit(options.model, fullest, obj, img, image_size);
    if (!f.ok) break;
    std::vector<double> rms;
    for (std::size_t k = 0; k < used.size(); ++k) rms.push_back(rms_of(project(options.model, board, f.rvecs[k], f.tvecs[k], f.K, f.D), img[k]));
    std::vector<double> sorted = rms;
    std::sort(sorted.begin(), sorted.end());
    const double limit = std::max(options.outlier_factor * sorted[sorted.size() / 2], options.max_view_rms_px);
    std::vector<std::size_t> keep;
    for (std::size_t k = 0; k < used.size(); ++k) {
      if (rms[k] <= limit) {
        keep.push_back(used[k]);
      } else {
        std::ostringstream s;
        s << "reprojection RMS " << rms[k] << " px above the limit " << limit << " px (unreliable detection)";
        res->views[used[k]].reason = s.str();
      }
    }
    if (keep.size() == used.size()) break;
    used = keep;
  }
  return used;
}

/// Distortion terms by K-fold cross-validation over views: each model's held-out and
/// training RMS in res->candidates; returns the index of the simplest model (fewest terms)
/// within min_improvement of the best.
std::size_t choose_model(const std::vector<Model>& models,
                         const std::vector<std::vector<cv::Point3f>>& obj,
                         const std::vector<std::vector<cv::Point2f>>& img, cv::Size image_size,
                         const IntrinsicsOptions& options, IntrinsicsResult* res) {
  const std::size_t views = obj.size();
  const int folds = std::min<int>(options.folds, static_cast<int>(views));
  double best = 1e18;
  for (std::size_t m = 0; m < models.size(); ++m) {
    double se = 0.0;
    int n = 0;
    for (int k = 0; k < folds; ++k) {
      std::vector<std::size_t> train, test;
      for (std::size_t i = 0; i < views; ++i)
        (static_cast<int>(i) % folds == k ? test : train).push_back(i);
      std::vector<std::vector<cv::Point3f>> o;
      std::vector<std::vector<cv::Point2f>> im;
      for (std::size_t i : train) {
        o.push_back(obj[i]);
        im.push_back(img[i]);
      }
      const Fit f = fit(options.model, models[m], o, im, image_size);
      if (!f.ok) {
        se = 1e18;
        break;
      }
      for (std::size_t i : test) {
        const double r = heldout_rms(options.model, obj[i], img[i], f.K, f.D);
        se += r * r * static_cast<double>(obj[i].size());
        n += static_cast<int>(obj[i].size());
      }
    }
    const Fit all = fit(options.model, models[m], obj, img, image_size);
    ModelCandidate c;
    c.terms = models[m].terms;
    c.heldout_rms_px = n > 0 ? std::sqrt(se / n) : 1e9;
    c.train_rms_px = all.ok ? all.rms : 1e9;
    res->candidates.push_back(c);
    best = std::min(best, c.heldout_rms_px);
  }
  // The simplest model (fewest terms) within min_improvement of the best.
  std::size_t pick = models.size() - 1;
  for (std::size_t m = 0; m < models.size(); ++m) {
    if (res->candidates[m].heldout_rms_px <= best * (1.0 + options.min_improvement) &&
        models[m].free.size() < models[pick].free.size()) {
      pick = m;
    } else if (res->candidates[m].heldout_rms_px <= best * (1.0 + options.min_improvement) &&
               models[m].free.size() == models[pick].free.size() &&
               res->candidates[m].heldout_rms_px < res->candidates[pick].heldout_rms_px) {
      pick = m;
    }
  }
  return pick;
}

/// The fit's intrinsics, its estimated parameters and their standard deviations in *res.
void set_intrinsics(const Fit& f, const Model& m, const std::vector<std::vector<cv::Point3f>>& obj,
                    const std::vector<std::vector<cv::Point2f>>& img, cv::Size image_size,
                    const IntrinsicsOptions& options, IntrinsicsResult* res) {
  res->distortion_terms = m.terms;
  res->rms_px = f.rms;
  auto& k = res->intrinsics;
  k.width = image_size.width;
  k.height = image_size.height;
  k.fx = f.K.at<double>(0, 0);
  k.fy = f.K.at<double>(1, 1);
  k.cx = f.K.at<double>(0, 2);
  k.cy = f.K.at<double>(1, 2);
  k.model = options.model;
  for (int i = 0; i < static_cast<int>(f.D.total()); ++i) k.distortion.push_back(f.D.at<double>(i));
  res->parameter_names = {"fx", "fy", "cx", "cy"};
  res->parameters = {k.fx, k.fy, k.cx, k.cy};
  static const char* kPlumb[] = {"k1", "k2", "p1", "p2", "k3"};
  static const char* kFish[] = {"k1", "k2", "k3", "k4"};
  for (int d : m.free) {
    res->parameter_names.push_back(options.model == DistortionModel::kEquidistant ? kFish[d]
                                                                                  : kPlumb[d]);
    res->parameters.push_back(k.distortion[static_cast<std::size_t>(d)]);
  }
  if (options.model == DistortionModel::kPlumbBob && !f.std_intrinsics.empty()) {
    // OpenCV's order: fx fy cx cy k1 k2 p1 p2 k3 ...
    for (int i = 0; i < 4; ++i) res->std_devs.push_back(f.std_intrinsics.at<double>(i));
    for (int d : m.free) res->std_devs.push_back(f.std_intrinsics.at<double>(4 + d));
  } else {
    res->std_devs = numeric_std(options.model, m, f, obj, img);
  }
}

/// Per-view errors and coverage: each used view's reprojection and RMS in res->views, and the
/// fraction of an 8 x 8 grid over the image that their points reach.
void set_view_errors(const Fit& f, const std::vector<std::size_t>& used,
                     const std::vector<cv::Point3f>& board, cv::Size image_size,
                     const IntrinsicsOptions& options, IntrinsicsResult* res) {
  cv::Mat cells(8, 8, CV_8U, cv::Scalar(0));
  for (std::size_t i = 0; i < used.size(); ++i) {
    auto& v = res->views[used[i]];
    v.used = true;
    v.reprojected = project(options.model, board, f.rvecs[i], f.tvecs[i], f.K, f.D);
    v.rms_px = rms_of(v.reprojected, v.points);
    for (const auto& p : v.points) {
      const int cx = std::clamp(static_cast<int>(p.x / image_size.width * 8), 0, 7);
      const int cy = std::clamp(static_cast<int>(p.y / image_size.height * 8), 0, 7);
      cells.at<uchar>(cy, cx) = 1;
    }
  }
  res->coverage = cv::countNonZero(cells) / 64.0;
}

}  // namespace

IntrinsicsResult calibrate_intrinsics(const std::vector<PatternDetection>& detections,
                                      const std::vector<std::string>& names, cv::Size image_size,
                                      const PatternSpec& pattern,
                                      const IntrinsicsOptions& options) {
  if (const std::string e = pattern.validate() + options.validate(); !e.empty())
    throw std::invalid_argument(e);
  if (names.size() != detections.size())
    throw std::invalid_argument("names and detections differ in size");
  IntrinsicsResult res;
  const std::vector<cv::Point3f> board = pattern.object_points();
  const auto models = candidate_models(options.model, options.select_distortion);
  std::vector<std::size_t> used = label_views(detections, names, &res);
  used = reject_outlier_views(detections, std::move(used), image_size, board, models.back(),
                              options, &res);
  if (static_cast<int>(used.size()) < options.min_views) {
    res.reason = "only " + std::to_string(used.size()) + " usable views, need " +
                 std::to_string(options.min_views);
    return res;
  }
  std::vector<std::vector<cv::Point3f>> obj;
  std::vector<std::vector<cv::Point2f>> img;
  gather(board, detections, used, &obj, &img);
  const std::size_t chosen = models.size() > 1
                                 ? choose_model(models, obj, img, image_size, options, &res)
                                 : models.size() - 1;
  const Model& m = models[chosen];
  const Fit f = fit(options.model, m, obj, img, image_size);
  if (!f.ok) {
    res.reason = "calibration did not converge";
    return res;
  }
  set_intrinsics(f, m, obj, img, image_size, options, &res);
  set_view_errors(f, used, board, image_size, options, &res);
  res.ok = true;
  return res;
}

}  // namespace rgbdt::calib_targets
