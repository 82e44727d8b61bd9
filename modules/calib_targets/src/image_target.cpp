#include "rgbdt/calib_targets/image_target.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <numeric>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::calib_targets {

namespace {

constexpr double kPi = 3.14159265358979323846;

double median_of(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

float bilinear(const cv::Mat& f, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x));
  const int y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= f.cols || y0 + 1 >= f.rows) return -1.0f;
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  return (1 - ay) * ((1 - ax) * f.at<float>(y0, x0) + ax * f.at<float>(y0, x0 + 1)) +
         ay * ((1 - ax) * f.at<float>(y0 + 1, x0) + ax * f.at<float>(y0 + 1, x0 + 1));
}

struct Candidate {
  cv::RotatedRect ellipse;
  double inside = 0.0, outside = 0.0;  ///< median levels of the hole and the board around it
  double score = 0.0;
  bool board_side = false;  ///< found as a hole of the board (its inside need not be homogeneous)
};

/// Hole/board levels: median inside the ellipse shrunk to 0.7, and in the ring 1.3-1.7.
bool levels(const cv::Mat& f, const cv::RotatedRect& e, double* inside, double* outside,
            double* ring_spread, double* inside_spread = nullptr) {
  std::vector<float> in, out;
  const double a = 0.5 * e.size.width, b = 0.5 * e.size.height;
  const double ang = e.angle * kPi / 180.0, ca = std::cos(ang), sa = std::sin(ang);
  const int R = static_cast<int>(std::ceil(1.8 * std::max(a, b)));
  const int step = std::max(1, R / 40);
  for (int dy = -R; dy <= R; dy += step) {
    for (int dx = -R; dx <= R; dx += step) {
      const int x = static_cast<int>(std::lround(e.center.x)) + dx;
      const int y = static_cast<int>(std::lround(e.center.y)) + dy;
      if (x < 0 || y < 0 || x >= f.cols || y >= f.rows) continue;
      const double u = (x - e.center.x) * ca + (y - e.center.y) * sa;
      const double v = -(x - e.center.x) * sa + (y - e.center.y) * ca;
      const double rho = std::sqrt(u * u / (a * a) + v * v / (b * b));
      if (rho < 0.7) in.push_back(f.at<float>(y, x));
      if (rho > 1.3 && rho < 1.7) out.push_back(f.at<float>(y, x));
    }
  }
  if (in.size() < 5 || out.size() < 10) return false;
  *inside = median_of(in);
  *outside = median_of(out);
  std::vector<float> dev;
  for (float v : out) dev.push_back(std::abs(v - static_cast<float>(*outside)));
  *ring_spread = 1.4826 * median_of(dev);
  if (inside_spread) {
    dev.clear();
    for (float v : in) dev.push_back(std::abs(v - static_cast<float>(*inside)));
    *inside_spread = 1.4826 * median_of(dev);
  }
  return true;
}

/// Downsampling factor of the candidate search: a power of two that keeps the smallest
/// plausible hole at least kMinCoarseAxisPx across (semi-axis) at the coarse level, at most 8.
int coarse_factor(double min_axis_px) {
  constexpr double kMinCoarseAxisPx = 6.0;
  int k = 1;
  while (k < 8 && min_axis_px / (2 * k) >= kMinCoarseAxisPx) k *= 2;
  return k;
}

/// f downsampled by k (area average) as 8-bit, for MSER.
cv::Mat coarse_u8(const cv::Mat& f, int k) {
  cv::Mat coarse, u8;
  if (k > 1) {
    cv::resize(f, coarse, cv::Size(f.cols / k, f.rows / k), 0, 0, cv::INTER_AREA);
  } else {
    coarse = f;
  }
  coarse.convertTo(u8, CV_8U, 255.0);
  return u8;
}

/// An MSER region's pixels as a mask over its box with a 1-pixel margin (so that its
/// outline is closed); findContours then needs the offset (box.x - 1, box.y - 1).
cv::Mat region_mask(const std::vector<cv::Point>& region, const cv::Rect& box) {
  cv::Mat mask(box.height + 2, box.width + 2, CV_8U, cv::Scalar(0));
  for (const cv::Point& p : region) mask.at<uchar>(p.y - box.y + 1, p.x - box.x + 1) = 255;
  return mask;
}

/// Nested MSERs of one hole: the best-scoring candidate per centre, best first. Equal scores
/// (a support fraction, a ratio of small counts, can tie exactly between nested outlines) are
/// ordered by the ellipse, larger first, then by centre, so that the choice does not depend on
/// the order in which OpenCV lists its regions.
std::vector<Candidate> best_per_centre(std::vector<Candidate> out) {
  const auto key = [](const Candidate& c) {
    const cv::RotatedRect& e = c.ellipse;
    return std::make_tuple(-c.score, -static_cast<double>(e.size.area()), e.center.x, e.center.y,
                           e.size.width, e.angle);
  };
  std::sort(out.begin(), out.end(), [&](const Candidate& x, const Candidate& y) { return key(x) < key(y); });
  std::vector<Candidate> unique;
  for (const Candidate& c : out) {
    bool dup = false;
    for (const Candidate& u : unique) {
      const double d = std::hypot(c.ellipse.center.x - u.ellipse.center.x, c.ellipse.center.y - u.ellipse.center.y);
      if (d < 0.5 * std::min(u.ellipse.size.width, u.ellipse.size.height)) dup = true;
    }
    if (!dup) unique.push_back(c);
  }
  return unique;
}

/// Elliptical dark or bright blobs of a plausible size: MSER on the 8-bit normalised image
/// downsampled by coarse_factor() (MSER's cost grows with the pixels; the hole is refined
/// at full resolution afterwards), ellipses and levels in full-resolution pixels.
std::vector<Candidate> find_candidates(const cv::Mat& f, double min_axis_px, double max_axis_px,
                                       const ImageDetectionOptions& o) {
  const int k = coarse_factor(min_axis_px);
  const cv::Mat u8 = coarse_u8(f, k);
  const double k2 = static_cast<double>(k) * k;
  const double min_area = std::max(20.0, kPi * min_axis_px * min_axis_px * o.min_axis_ratio / k2);
  const double max_area = std::min(0.5 * static_cast<double>(u8.total()), kPi * max_axis_px * max_axis_px / k2);
  std::vector<Candidate> out;
  int stats[7] = {0, 0, 0, 0, 0, 0, 0};
  // One call finds the dark regions and the bright ones: OpenCV's MSER on an 8-bit image
  // runs both passes itself (on the inverted image it returns the same regions again).
  auto mser = cv::MSER::create(5, static_cast<int>(min_area), static_cast<int>(max_area), 0.25);
  std::vector<std::vector<cv::Point>> regions;
  std::vector<cv::Rect> boxes;
  mser->detectRegions(u8, regions, boxes);
  for (std::size_t ri = 0; ri < regions.size(); ++ri) {
    const auto& reg = regions[ri];
    ++stats[4];
    if (reg.size() < 6) continue;
    // The region's outline (MSER pixel lists are not a boundary and may repeat pixels).
    const cv::Rect box = boxes[ri];
    const cv::Mat mask = region_mask(reg, box);
    const double area = cv::countNonZero(mask);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, cv::Point(box.x - 1, box.y - 1));
    if (contours.size() != 1 || contours[0].size() < 6) continue;
    cv::RotatedRect e = cv::fitEllipse(contours[0]);
    // Coarse pixel centres -> full-resolution pixel centres.
    e.center = cv::Point2f(static_cast<float>((e.center.x + 0.5) * k - 0.5), static_cast<float>((e.center.y + 0.5) * k - 0.5));
    e.size = cv::Size2f(e.size.width * static_cast<float>(k), e.size.height * static_cast<float>(k));
    const double a = 0.5 * std::max(e.size.width, e.size.height);
    const double b = 0.5 * std::min(e.size.width, e.size.height);
    if (!(b > k) || b / a < o.min_axis_ratio || a > max_axis_px || a < min_axis_px) continue;
    ++stats[5];
    const double fill = area * k2 / (kPi * a * b);
    if (fill < 0.9 || fill > 1.1) continue;
    ++stats[6];
    if (e.center.x - a < 1 || e.center.y - a < 1 || e.center.x + a > f.cols - 2 ||
        e.center.y + a > f.rows - 2) {
      continue;
    }
    Candidate c;
    c.ellipse = e;
    double spread = 0.0, in_spread = 0.0;
    ++stats[0];
    if (!levels(f, e, &c.inside, &c.outside, &spread, &in_spread)) continue;
    const double contrast = std::abs(c.outside - c.inside);
    ++stats[1];
    if (contrast < o.min_contrast) continue;
    ++stats[2];
    // A hole: homogeneous inside, enclosed by a homogeneous board.
    if (spread > 0.35 * contrast || in_spread > 0.35 * contrast) continue;
    ++stats[3];
    c.score = contrast / (spread + in_spread + 0.02);
    out.push_back(c);
  }
  core::log_debug("calib_targets: MSER regions ", stats[4], ", size ok ", stats[5], ", elliptical ",
                  stats[6], ", inside image ", stats[0], ", levels ", stats[1], ", contrast ", stats[2],
                  ", homogeneous ", stats[3]);
  return best_per_centre(std::move(out));
}

/// Chooses one candidate per layout hole: an affine map board -> image consistent with the
/// layout, board y pointing up in the image. Returns candidate indices in layout order.
/// With `seed_board_half` set, a selection must also put `seed` on the board: mapped back
/// through the affine fit, within these half extents of the board centre.
std::vector<int> match_layout_image(const std::vector<Eigen::Vector2d>& layout,
                                    const std::vector<Candidate>& cand, const Eigen::Vector2d& up,
                                    std::string* reason, const std::optional<Eigen::Vector2d>& seed = {},
                                    const Eigen::Vector2d& seed_board_half = Eigen::Vector2d::Zero(),
                                    double radius_m = 0.0, std::size_t pool_size = 9) {
  const std::size_t n = layout.size();
  if (cand.size() < n) {
    *reason = "found " + std::to_string(cand.size()) + " hole-like region(s), the target has " +
              std::to_string(n);
    return {};
  }
  if (n == 1) return {0};
  const std::size_t k = std::min<std::size_t>(cand.size(), pool_size);
  double best = 1e18;
  std::vector<int> best_pick;
  std::vector<int> pick(n);
  std::vector<int> pool(k);
  std::iota(pool.begin(), pool.end(), 0);
  // Ordered selections of n of the k best candidates (k <= 9, n <= 4 typically).
  std::vector<bool> used(k, false);
  std::function<void(std::size_t)> rec = [&](std::size_t depth) {
    if (depth == n) {
      // Affine fit: [u v] = A [x y 1].
      Eigen::MatrixXd M(static_cast<Eigen::Index>(n), 3);
      Eigen::MatrixXd P(static_cast<Eigen::Index>(n), 2);
      double size = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const auto& e = cand[static_cast<std::size_t>(pick[i])].ellipse;
        M.row(static_cast<Eigen::Index>(i)) << layout[i].x(), layout[i].y(), 1.0;
        P.row(static_cast<Eigen::Index>(i)) << e.center.x, e.center.y;
        size += 0.5 * std::max(e.size.width, e.size.height) / static_cast<double>(n);
      }
      const Eigen::MatrixXd A = M.colPivHouseholderQr().solve(P);
      const double rms = std::sqrt((M * A - P).squaredNorm() / static_cast<double>(n));
      const Eigen::Vector2d ax = A.row(0).transpose(), ay = A.row(1).transpose();
      // Board y must point up in the image: within 45 deg of `up` (a 2-row layout's
      // rotation by 90 deg fits its centres about as well as the right one).
      if (ay.dot(up) <= std::sqrt(0.5) * ay.norm()) return;
      if (ax.x() * ay.y() - ax.y() * ay.x() >= 0) return;  // x right of y (image v is down)
      if (radius_m > 0.0) {
        // Each hole as large as the layout's scale makes a hole of the target's radius
        // (within the spread a lens's distortion and the board's tilt give).
        Eigen::Matrix2d L;
        L << ax, ay;
        const Eigen::JacobiSVD<Eigen::Matrix2d> svd(L);
        const double expected = svd.singularValues()(0) * radius_m;
        for (std::size_t i = 0; i < n; ++i) {
          const auto& e = cand[static_cast<std::size_t>(pick[i])].ellipse;
          const double a = 0.5 * std::max(e.size.width, e.size.height);
          if (a < 0.7 * expected || a > 1.4 * expected) return;
        }
      }
      if (seed) {
        Eigen::Matrix2d L;
        L << ax, ay;
        const Eigen::Vector2d board = L.inverse() * (*seed - A.row(2).transpose());
        if (std::abs(board.x()) > seed_board_half.x() || std::abs(board.y()) > seed_board_half.y()) return;
      }
      const double cost = rms / size;
      if (cost < best) {
        best = cost;
        best_pick = pick;
      }
      return;
    }
    for (std::size_t i = 0; i < k; ++i) {
      if (used[i]) continue;
      used[i] = true;
      pick[depth] = static_cast<int>(i);
      rec(depth + 1);
      used[i] = false;
    }
  };
  rec(0);
  if (best_pick.empty() || best > 0.3) {
    *reason = "no set of " + std::to_string(n) + " holes matches the target's layout" +
              (seed ? " with the seed on the board" : "");
    return {};
  }
  return best_pick;
}

}  // namespace

std::string ImageDetectionOptions::validate() const {
  std::ostringstream s;
  if (!(epsilon_fraction > 0 && epsilon_fraction < 1)) s << "epsilon_fraction = " << epsilon_fraction << " must be in (0, 1); ";
  if (seed_guard_fraction < 0) s << "seed_guard_fraction = " << seed_guard_fraction << " must be >= 0; ";
  if (!(low_percentile >= 0 && high_percentile <= 100 && low_percentile < high_percentile)) s << "percentiles must satisfy 0 <= low < high <= 100; ";
  if (smoothing_sigma_px < 0) s << "smoothing_sigma_px must be >= 0; ";
  if (!(min_range_m > 0 && max_range_m > min_range_m)) s << "need 0 < min_range_m < max_range_m; ";
  if (!(min_axis_ratio > 0 && min_axis_ratio <= 1)) s << "min_axis_ratio must be in (0, 1]; ";
  if (!(edge_search_px > 0)) s << "edge_search_px must be > 0; ";
  if (up_image.norm() < 1e-9) s << "up_image must be non-zero; ";
  return s.str();
}

cv::Mat normalise_image(const cv::Mat& image, double low_percentile, double high_percentile) {
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  } else {
    grey = image;
  }
  cv::Mat f;
  grey.convertTo(f, CV_32F);
  std::vector<float> v;
  v.reserve(f.total() / 4 + 1);
  for (int y = 0; y < f.rows; y += 2) {
    for (int x = 0; x < f.cols; x += 2) v.push_back(f.at<float>(y, x));
  }
  // The two order statistics by selection, not a sort of the whole sample: the same values
  // in linear time (the higher rank is selected among the values above the lower one).
  const auto rank = [&](double p) {
    return std::min(v.size() - 1, static_cast<std::size_t>(p / 100.0 * static_cast<double>(v.size())));
  };
  const std::size_t lo_rank = rank(low_percentile), hi_rank = rank(high_percentile);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(lo_rank), v.end());
  const float lo = v[lo_rank];
  std::nth_element(v.begin() + static_cast<std::ptrdiff_t>(lo_rank), v.begin() + static_cast<std::ptrdiff_t>(hi_rank),
                   v.end());
  const float hi = v[hi_rank];
  const float scale = hi > lo ? 1.0f / (hi - lo) : 1.0f;
  f = (f - lo) * scale;
  cv::min(f, 1.0, f);
  cv::max(f, 0.0, f);
  return f;
}

std::vector<Eigen::Vector2i> grow_region(const cv::Mat& f, const Eigen::Vector2i& seed,
                                         double epsilon, double seed_guard, cv::Mat* region_out,
                                         std::size_t max_pixels) {
  // Algorithm 1, lines 1-2: BI = ones; here 255 = not in the region ("1"), 0 = region.
  cv::Mat bi(f.rows, f.cols, CV_8U, cv::Scalar(255));
  std::deque<Eigen::Vector2i> queue;  // lines 3-4
  std::vector<Eigen::Vector2i> list;  // line 5: L
  const float seed_level = f.at<float>(seed.y(), seed.x());
  queue.push_back(seed);
  list.push_back(seed);
  bi.at<uchar>(seed.y(), seed.x()) = 0;
  while (!queue.empty()) {  // line 6
    const Eigen::Vector2i p = queue.front();  // lines 7-8
    queue.pop_front();
    const float ip = f.at<float>(p.y(), p.x());
    for (int dy = -1; dy <= 1; ++dy) {  // line 9: 8-neighbourhood
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const int x = p.x() + dx, y = p.y() + dy;
        if (x < 0 || y < 0 || x >= f.cols || y >= f.rows) continue;
        const float in = f.at<float>(y, x);
        if (std::abs(in - ip) > epsilon) continue;  // line 11
        if (seed_guard > 0 && std::abs(in - seed_level) > seed_guard) continue;
        if (bi.at<uchar>(y, x) == 0) continue;  // line 13
        queue.emplace_back(x, y);               // lines 15-17
        list.emplace_back(x, y);
        bi.at<uchar>(y, x) = 0;
      }
    }
    if (list.size() > max_pixels) return {};
  }
  std::vector<Eigen::Vector2i> boundary;  // lines 22-32
  for (const Eigen::Vector2i& p : list) {
    bool edge = false;
    for (int dy = -1; dy <= 1 && !edge; ++dy) {
      for (int dx = -1; dx <= 1 && !edge; ++dx) {
        const int x = p.x() + dx, y = p.y() + dy;
        if (x < 0 || y < 0 || x >= f.cols || y >= f.rows || bi.at<uchar>(y, x) == 255) edge = true;
      }
    }
    if (edge) boundary.push_back(p);
  }
  if (region_out) *region_out = 255 - bi;
  return boundary;
}

namespace {

/// Why the image cannot be searched for the target; empty when it can.
std::string image_problem(const cv::Mat& image, const core::PinholeCamera& camera) {
  if (image.empty()) return "empty image";
  if (image.cols != camera.width() || image.rows != camera.height()) {
    return "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
           " but the camera '" + camera.intrinsics().camera_name + "' expects " +
           std::to_string(camera.width()) + "x" + std::to_string(camera.height());
  }
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    return "image depth must be 8 or 16 bit unsigned";
  }
  return "";
}

/// The smoothed image of a region of f. GaussianBlur reads the pixels around a sub-matrix,
/// so a region's result equals the same region of the whole.
cv::Mat smoothed(const cv::Mat& f, const cv::Rect& roi, const ImageDetectionOptions& options) {
  cv::Mat out;
  if (options.smoothing_sigma_px > 0)
    cv::GaussianBlur(f(roi), out, cv::Size(), options.smoothing_sigma_px);
  else
    out = f(roi);
  return out;
}

/// What the candidate search looks for: the target's hole layout and the range of hole
/// semi-axes in the image [px].
struct HoleSearch {
  std::vector<Eigen::Vector2d> layout;
  double min_axis = 0.0, max_axis = 0.0;
};

/// The candidates nearest the seed first (stable: equally near ones keep their order).
void sort_nearest_first(const Eigen::Vector2d& seed_px, std::vector<Candidate>* cand) {
  const auto dist = [&](const Candidate& c) {
    return std::hypot(c.ellipse.center.x - seed_px.x(), c.ellipse.center.y - seed_px.y());
  };
  std::stable_sort(cand->begin(), cand->end(), [&](const Candidate& a, const Candidate& b) { return dist(a) < dist(b); });
}

/// Half the board's extents [m]: from the target's board size, else the layout's plus two radii.
Eigen::Vector2d board_half_extent(const core::TargetSpec& target, const std::vector<Eigen::Vector2d>& layout) {
  if (target.board_size_m) return 0.5 * *target.board_size_m;
  Eigen::Vector2d half = Eigen::Vector2d::Zero();
  for (const auto& h : layout) half = half.cwiseMax(h.cwiseAbs());
  half.array() += 2.0 * target.radius_m;
  return half;
}

/// A multi-hole board with a seed: the seed (anywhere on the board) picks the layout match
/// that has it on the board; the candidates nearest the seed are tried first. False, with
/// the reason, when none matches.
bool pick_layout_near_seed(const cv::Mat& f, const core::TargetSpec& target,
                           const HoleSearch& search, const Eigen::Vector2d& seed_px,
                           const ImageDetectionOptions& options, std::vector<Candidate>* chosen,
                           std::string* reason) {
  auto cand = find_candidates(f, search.min_axis, search.max_axis, options);
  sort_nearest_first(seed_px, &cand);
  std::string why;
  const auto pick = match_layout_image(search.layout, cand, options.up_image.normalized(), &why, seed_px,
                                       board_half_extent(target, search.layout));
  if (pick.empty()) {
    *reason = why;
    return false;
  }
  for (int i : pick) chosen->push_back(cand[static_cast<std::size_t>(i)]);
  return true;
}

/// The seed picks among the hole candidates the automatic search finds: the smallest
/// one that contains it (none when no candidate does).
std::optional<Candidate> candidate_around_seed(const cv::Mat& f, const HoleSearch& search,
                                               const Eigen::Vector2d& seed_px,
                                               const ImageDetectionOptions& options) {
  const auto cand = find_candidates(f, search.min_axis, search.max_axis, options);
  int best = -1;
  double best_area = 0.0;
  for (std::size_t i = 0; i < cand.size(); ++i) {
    const cv::RotatedRect& e = cand[i].ellipse;
    const double a = 0.5 * e.size.width, b = 0.5 * e.size.height;
    if (!(a > 0 && b > 0)) continue;
    const double th = e.angle * kPi / 180.0;
    const double dx = seed_px.x() - e.center.x, dy = seed_px.y() - e.center.y;
    const double u = std::cos(th) * dx + std::sin(th) * dy,
                 v = -std::sin(th) * dx + std::cos(th) * dy;
    if ((u * u) / (a * a) + (v * v) / (b * b) > 1.0) continue;
    if (best < 0 || a * b < best_area) {
      best = static_cast<int>(i);
      best_area = a * b;
    }
  }
  if (best < 0) return std::nullopt;
  return cand[static_cast<std::size_t>(best)];
}

/// The hole from the seed's own region: contrast from the seed's region grown with a loose
/// threshold, its ring gives the board. False, with the reason, when that region is no hole.
bool hole_from_seed_region(const cv::Mat& f, const HoleSearch& search,
                           const Eigen::Vector2d& seed_px, const ImageDetectionOptions& options,
                           std::vector<Candidate>* chosen, std::string* reason) {
  const Eigen::Vector2i s = seed_px.array().round().cast<int>();
  cv::Mat region;
  const auto bnd =
      grow_region(smoothed(f, cv::Rect(0, 0, f.cols, f.rows), options), s, 0.05, 0.25, &region,
                  static_cast<std::size_t>(kPi * search.max_axis * search.max_axis));
  std::vector<cv::Point> pts;
  for (const auto& b : bnd) pts.emplace_back(b.x(), b.y());
  if (pts.size() < 6) {
    *reason = "the seed's region is not a hole (it leaks into the background or is tiny)";
    return false;
  }
  Candidate c;
  c.ellipse = cv::fitEllipse(pts);
  double spread = 0.0;
  if (!levels(f, c.ellipse, &c.inside, &c.outside, &spread) ||
      std::abs(c.outside - c.inside) < options.min_contrast) {
    *reason = "the seed's region has no contrast with its surroundings";
    return false;
  }
  chosen->push_back(c);
  return true;
}

/// The candidates that become the target's holes, in layout order (seed: see
/// detect_target_in_image). False, with the reason, when the image shows no target.
bool choose_candidates(const cv::Mat& f, const core::TargetSpec& target, const HoleSearch& search,
                       const std::optional<Eigen::Vector2d>& seed_px,
                       const ImageDetectionOptions& options, std::vector<Candidate>* chosen,
                       std::string* reason) {
  if (!seed_px) {
    const auto cand = find_candidates(f, search.min_axis, search.max_axis, options);
    std::string why;
    const auto pick = match_layout_image(search.layout, cand, options.up_image.normalized(), &why);
    if (pick.empty()) {
      *reason = why;
      return false;
    }
    for (int i : pick) chosen->push_back(cand[static_cast<std::size_t>(i)]);
    return true;
  }
  if (search.layout.size() > 1) {
    return pick_layout_near_seed(f, target, search, *seed_px, options, chosen, reason);
  }
  // Only when no candidate contains the seed, the seed's own region (grown with a loose
  // threshold) gives the hole; on blurred thermal edges that region can leak out of the
  // hole into an ellipse several times too large, which then misleads the calibration.
  if (const std::optional<Candidate> around = candidate_around_seed(f, search, *seed_px, options)) {
    chosen->push_back(*around);
  }
  if (chosen->empty() && search.layout.size() == 1) {
    return hole_from_seed_region(f, search, *seed_px, options, chosen, reason);
  }
  return true;
}

/// A hole's region grown by Algorithm 1.
struct HoleRegion {
  cv::Rect roi;                              ///< the window it was grown in
  cv::Mat smooth;                            ///< the smoothed image over roi
  cv::Mat region;                            ///< its mask over roi
  std::vector<Eigen::Vector2i> boundary_px;  ///< its boundary pixels in the image
};

/// Algorithm 1 from `seed` for the hole of candidate c, with thresholds from its contrast.
HoleRegion grow_hole_region(const cv::Mat& f, const Candidate& c, const Eigen::Vector2i& seed,
                            const ImageDetectionOptions& options) {
  const double contrast = std::abs(c.outside - c.inside);
  const double expected_area = kPi * 0.25 * c.ellipse.size.width * c.ellipse.size.height;
  const cv::Rect whole(0, 0, f.cols, f.rows);
  // Algorithm 1 and the edge refinement within 2.5 semi-axes of the hole; the whole image
  // only when the region reaches that window's border (a leak, or a seed outside it).
  const double reach = 2.5 * 0.5 * std::max(c.ellipse.size.width, c.ellipse.size.height) +
                       options.edge_search_px + 3;
  HoleRegion r;
  r.roi = cv::Rect(static_cast<int>(std::floor(c.ellipse.center.x - reach)),
                   static_cast<int>(std::floor(c.ellipse.center.y - reach)),
                   static_cast<int>(std::ceil(2 * reach)) + 1,
                   static_cast<int>(std::ceil(2 * reach)) + 1);
  r.roi &= whole;
  if (!r.roi.contains(cv::Point(seed.x(), seed.y()))) r.roi = whole;
  r.smooth = smoothed(f, r.roi, options);
  const auto grow = [&] {
    r.boundary_px =
        grow_region(r.smooth, seed - Eigen::Vector2i(r.roi.x, r.roi.y),
                    options.epsilon_fraction * contrast, options.seed_guard_fraction * contrast,
                    &r.region, static_cast<std::size_t>(3.0 * expected_area) + 100);
  };
  grow();
  const auto touches_window = [&] {
    for (const Eigen::Vector2i& b : r.boundary_px) {
      if ((b.x() == 0 && r.roi.x > 0) || (b.y() == 0 && r.roi.y > 0) ||
          (b.x() == r.roi.width - 1 && r.roi.x + r.roi.width < f.cols) ||
          (b.y() == r.roi.height - 1 && r.roi.y + r.roi.height < f.rows))
        return true;
    }
    return false;
  };
  if (r.roi != whole && touches_window()) {
    r.roi = whole;
    r.smooth = smoothed(f, r.roi, options);
    grow();
  }
  for (Eigen::Vector2i& b : r.boundary_px) b += Eigen::Vector2i(r.roi.x, r.roi.y);
  return r;
}

/// Sub-pixel edges: the mid-level crossing along the gradient through each boundary pixel.
std::vector<Eigen::Vector2d> subpixel_edges(const cv::Mat& f, const HoleRegion& r,
                                            const Candidate& c,
                                            const ImageDetectionOptions& options) {
  std::vector<Eigen::Vector2d> edges;
  cv::Mat gx, gy;
  cv::Sobel(r.smooth, gx, CV_32F, 1, 0, 3);
  cv::Sobel(r.smooth, gy, CV_32F, 0, 1, 3);
  const double mid = 0.5 * (c.inside + c.outside);
  for (const Eigen::Vector2i& b : r.boundary_px) {
    Eigen::Vector2d d(gx.at<float>(b.y() - r.roi.y, b.x() - r.roi.x),
                      gy.at<float>(b.y() - r.roi.y, b.x() - r.roi.x));
    const Eigen::Vector2d radial =
        (b.cast<double>() - Eigen::Vector2d(c.ellipse.center.x, c.ellipse.center.y)).normalized();
    if (d.norm() < 1e-6) d = radial;
    d.normalize();
    if (d.dot(radial) < 0) d = -d;  // outwards
    double best_t = 1e9;
    const double step = 0.1;
    double prev = bilinear(f, b.x() - options.edge_search_px * d.x(),
                           b.y() - options.edge_search_px * d.y()) -
                  mid;
    for (double t = -options.edge_search_px + step; t <= options.edge_search_px + 1e-9; t += step) {
      const float v = bilinear(f, b.x() + t * d.x(), b.y() + t * d.y());
      if (v < 0) break;
      const double cur = v - mid;
      if ((prev < 0) != (cur < 0) && std::abs(t) < std::abs(best_t)) {
        best_t = t - step * cur / (cur - prev);  // linear interpolation of the crossing
      }
      prev = cur;
    }
    if (best_t < 1e8) edges.push_back(b.cast<double>() + best_t * d);
  }
  return edges;
}

/// hole->ellipse through its edge points; edge points far from it (noise, neighbouring
/// structures) are dropped and the ellipse refit.
void fit_hole_ellipse(ImageHole* hole) {
  std::vector<cv::Point2f> ep;
  for (const auto& p : hole->edge_points_px)
    ep.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  hole->ellipse = cv::fitEllipse(ep);
  std::vector<Eigen::Vector2d> kept;
  const double a = 0.5 * hole->ellipse.size.width, bb = 0.5 * hole->ellipse.size.height;
  const double ang = hole->ellipse.angle * kPi / 180.0;
  for (const auto& p : hole->edge_points_px) {
    const double dx = p.x() - hole->ellipse.center.x, dy = p.y() - hole->ellipse.center.y;
    const double u = dx * std::cos(ang) + dy * std::sin(ang),
                 v = -dx * std::sin(ang) + dy * std::cos(ang);
    const double rho = std::sqrt(u * u / (a * a) + v * v / (bb * bb));
    if (std::abs(rho - 1.0) * std::min(a, bb) < 1.5) kept.push_back(p);
  }
  if (kept.size() >= 6 && kept.size() < hole->edge_points_px.size()) {
    hole->edge_points_px = kept;
    ep.clear();
    for (const auto& p : kept)
      ep.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    hole->ellipse = cv::fitEllipse(ep);
  }
}

std::vector<Eigen::Vector2d> board_side_edges(const cv::Mat& f, const Candidate& c,
                                              const ImageDetectionOptions& options);

/// Hole h of the target from candidate c: its region grown from `seed`, sub-pixel edges and
/// ellipse. False, with the reason, when the region or its edges do not make a hole.
bool trace_hole(const cv::Mat& f, const Candidate& c, std::size_t h, const Eigen::Vector2i& seed,
                const ImageDetectionOptions& options, ImageHole* hole, std::string* reason) {
  const double contrast = std::abs(c.outside - c.inside);
  if (c.board_side) {
    hole->dark = c.inside < c.outside;
    hole->contrast = contrast;
    hole->edge_points_px = board_side_edges(f, c, options);
    // At least half the outline, so that the ellipse rests on the hole all round.
    const double circumference = kPi * 0.5 * (c.ellipse.size.width + c.ellipse.size.height);
    if (static_cast<double>(hole->edge_points_px.size()) <
        0.5 * std::clamp(2.0 * circumference / 2.0, 64.0, 720.0)) {
      *reason = "hole " + std::to_string(h) + ": the board's edge around it is found on " +
                std::to_string(hole->edge_points_px.size()) + " rays only";
      return false;
    }
    fit_hole_ellipse(hole);
    hole->center_px = Eigen::Vector2d(hole->ellipse.center.x, hole->ellipse.center.y);
    for (const auto& p : hole->edge_points_px) hole->boundary_px.push_back(p.array().round().cast<int>());
    return true;
  }
  const double expected_area = kPi * 0.25 * c.ellipse.size.width * c.ellipse.size.height;
  const HoleRegion r = grow_hole_region(f, c, seed, options);
  hole->boundary_px = r.boundary_px;
  const double area = cv::countNonZero(r.region);
  if (hole->boundary_px.empty() || area < 0.4 * expected_area) {
    *reason = "hole " + std::to_string(h) + ": region growing gave " +
              std::to_string(static_cast<int>(area)) + " px, expected about " +
              std::to_string(static_cast<int>(expected_area));
    return false;
  }
  hole->dark = c.inside < c.outside;
  hole->contrast = contrast;
  hole->edge_points_px = subpixel_edges(f, r, c, options);
  if (hole->edge_points_px.size() < 6) {
    *reason = "hole " + std::to_string(h) + ": too few sub-pixel edge points";
    return false;
  }
  fit_hole_ellipse(hole);
  hole->center_px = Eigen::Vector2d(hole->ellipse.center.x, hole->ellipse.center.y);
  return true;
}

/// Three rounds of "the board's edge around the candidate, the ellipse through it": the
/// candidate becomes that ellipse; returns the fraction of rays whose edge point lies on it
/// (0 when fewer than 30 % of the rays find the board's edge, or the levels fail).
double refine_board_hole(const cv::Mat& f, const ImageDetectionOptions& o, Candidate* c) {
  double support = 0.0;
  for (int round = 0; round < 3; ++round) {
    const double a = 0.5 * c->ellipse.size.width, b = 0.5 * c->ellipse.size.height;
    const double rays = std::clamp(2.0 * kPi * std::max(a, b), 64.0, 720.0);
    ImageHole hole;
    hole.edge_points_px = board_side_edges(f, *c, o);
    if (static_cast<double>(hole.edge_points_px.size()) < 0.3 * rays) return 0.0;
    fit_hole_ellipse(&hole);
    support = static_cast<double>(hole.edge_points_px.size()) / rays;
    c->ellipse = hole.ellipse;
    double spread = 0.0;
    if (!levels(f, c->ellipse, &c->inside, &c->outside, &spread)) return 0.0;
  }
  return support;
}

/// Holes seen as the board's own holes: the inner outlines of large, homogeneous MSER
/// regions (the board, bright or dark) that are ellipses of a plausible size. For holes
/// whose inside is not homogeneous (a checkerboard or a door behind them), which the hole
/// search (find_candidates) cannot take for holes; the board around them still is.
std::vector<Candidate> find_board_hole_candidates(const cv::Mat& f, double min_axis_px, double max_axis_px,
                                                  const ImageDetectionOptions& o) {
  const int k = std::max(2, coarse_factor(min_axis_px));
  const cv::Mat u8 = coarse_u8(f, k);
  const double k2 = static_cast<double>(k) * k;
  // The board holds the holes: larger than a few of the smallest ones.
  const double min_area = std::max(100.0, 4.0 * kPi * min_axis_px * min_axis_px / k2);
  const double max_area = 0.8 * static_cast<double>(u8.total());
  std::vector<Candidate> out;
  // Bright boards and dark ones in one call (see find_candidates).
  auto mser = cv::MSER::create(5, static_cast<int>(min_area), static_cast<int>(max_area), 0.25);
  std::vector<std::vector<cv::Point>> regions;
  std::vector<cv::Rect> boxes;
  mser->detectRegions(u8, regions, boxes);
  for (std::size_t ri = 0; ri < regions.size(); ++ri) {
    const cv::Rect box = boxes[ri];
    const cv::Mat mask = region_mask(regions[ri], box);
    std::vector<std::vector<cv::Point>> contours;
    std::vector<cv::Vec4i> hierarchy;
    cv::findContours(mask, contours, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_NONE,
                     cv::Point(box.x - 1, box.y - 1));
    for (std::size_t ci = 0; ci < contours.size(); ++ci) {
      if (hierarchy[ci][3] < 0 || contours[ci].size() < 12) continue;  // inner outlines only
      // Bright parts of the background touching the edge join the board and bite into
      // the hole's outline: its convex hull restores the outline around them.
      std::vector<cv::Point> hull;
      cv::convexHull(contours[ci], hull);
      if (hull.size() < 6) continue;
      const cv::RotatedRect ec = cv::fitEllipse(hull);
      const double ac = 0.5 * std::max(ec.size.width, ec.size.height);
      const double bc = 0.5 * std::min(ec.size.width, ec.size.height);
      if (!(bc > 3.0)) continue;
      // An ellipse, not a marker's square: every hull vertex within 12 % (and a pixel)
      // of the fitted ellipse (a square's corners lie about 20 % outside it).
      const double ang = ec.angle * kPi / 180.0;
      bool elliptical = true;
      for (const cv::Point& q : hull) {
        const double dx = q.x - ec.center.x, dy = q.y - ec.center.y;
        const double u = dx * std::cos(ang) + dy * std::sin(ang), v = -dx * std::sin(ang) + dy * std::cos(ang);
        const double rho = std::sqrt(u * u / std::pow(0.5 * ec.size.width, 2) + v * v / std::pow(0.5 * ec.size.height, 2));
        if (std::abs(rho - 1.0) > 0.12 + 1.0 / bc) {
          elliptical = false;
          break;
        }
      }
      if (!elliptical) continue;
      cv::RotatedRect e = ec;
      e.center = cv::Point2f(static_cast<float>((ec.center.x + 0.5) * k - 0.5), static_cast<float>((ec.center.y + 0.5) * k - 0.5));
      e.size = cv::Size2f(ec.size.width * static_cast<float>(k), ec.size.height * static_cast<float>(k));
      const double a = ac * k, b = bc * k;
      if (b / a < o.min_axis_ratio || a > max_axis_px || a < min_axis_px) continue;
      if (e.center.x - 1.8 * a < 1 || e.center.y - 1.8 * a < 1 || e.center.x + 1.8 * a > f.cols - 2 ||
          e.center.y + 1.8 * a > f.rows - 2) {
        continue;
      }
      Candidate c;
      c.ellipse = e;
      c.board_side = true;
      double spread = 0.0;
      if (!levels(f, e, &c.inside, &c.outside, &spread)) continue;
      const double contrast = std::abs(c.outside - c.inside);
      // The board around the hole is homogeneous; the inside may be anything but the board.
      if (contrast < o.min_contrast || spread > 0.35 * contrast) continue;
      c.score = contrast / (spread + 0.02);
      out.push_back(c);
    }
  }
  // Each outline is a start: the board's edge around it (board_side_edges) fits the hole's
  // ellipse, which gives the next start. A hole seen only in part (a piece of its outline)
  // grows to the whole hole; the score is the fraction of rays whose edge lies on the final
  // ellipse (within 1.5 px): most of them for a hole, few for anything else.
  std::vector<Candidate> refined;
  for (Candidate c : out) {
    const double support = refine_board_hole(f, o, &c);
    const double a = 0.5 * std::max(c.ellipse.size.width, c.ellipse.size.height);
    const double b = 0.5 * std::min(c.ellipse.size.width, c.ellipse.size.height);
    if (support < 0.6 || !(b > 0) || b / a < o.min_axis_ratio || a > max_axis_px || a < min_axis_px) continue;
    c.score = support;
    refined.push_back(c);
  }
  out = std::move(refined);
  return best_per_centre(std::move(out));
}

/// Edges of a hole found from the board's side: along rays from the candidate's centre,
/// starting on the board (1.4 x the ellipse's radius in that direction) and walking
/// inwards, the first crossing of the level midway between the board and the hole
/// (linearly interpolated on the smoothed image). What lies inside the hole need not be
/// homogeneous: the walk stops where the board ends. Rays that reach 0.6 of the radius
/// without leaving the board (a bright part of the background right at the edge) give no
/// point; fit_hole_ellipse drops those that stop early on the background's own structure.
std::vector<Eigen::Vector2d> board_side_edges(const cv::Mat& f, const Candidate& c,
                                              const ImageDetectionOptions& options) {
  const double a = 0.5 * c.ellipse.size.width, b = 0.5 * c.ellipse.size.height;
  const double reach = 1.6 * std::max(a, b) + 3.0;
  cv::Rect roi(static_cast<int>(std::floor(c.ellipse.center.x - reach)),
               static_cast<int>(std::floor(c.ellipse.center.y - reach)), static_cast<int>(std::ceil(2 * reach)) + 1,
               static_cast<int>(std::ceil(2 * reach)) + 1);
  roi &= cv::Rect(0, 0, f.cols, f.rows);
  const cv::Mat smooth = smoothed(f, roi, options);
  const bool board_brighter = c.outside > c.inside;
  const double mid = 0.5 * (c.inside + c.outside);
  const double ang = c.ellipse.angle * kPi / 180.0;
  const int rays = std::clamp(static_cast<int>(2.0 * kPi * std::max(a, b)), 64, 720);
  std::vector<Eigen::Vector2d> edges;
  for (int i = 0; i < rays; ++i) {
    const double th = 2.0 * kPi * i / rays;
    // The ellipse's radius in this direction (its axes rotated by `ang`).
    const double ct = std::cos(th - ang), st = std::sin(th - ang);
    const double r = 1.0 / std::sqrt(ct * ct / (a * a) + st * st / (b * b));
    const Eigen::Vector2d d(std::cos(th), std::sin(th));
    const double step = 0.25;
    double prev = 0.0;
    bool have_prev = false;
    for (double t = 1.4 * r; t >= 0.6 * r; t -= step) {
      const double x = c.ellipse.center.x + t * d.x() - roi.x, y = c.ellipse.center.y + t * d.y() - roi.y;
      if (x < 0 || y < 0 || x > smooth.cols - 2 || y > smooth.rows - 2) break;
      const double cur = (bilinear(smooth, x, y) - mid) * (board_brighter ? 1.0 : -1.0);  // > 0 on the board
      if (have_prev && prev > 0 && cur <= 0) {
        const double t_cross = t + step * cur / (cur - prev);
        edges.emplace_back(c.ellipse.center.x + t_cross * d.x(), c.ellipse.center.y + t_cross * d.y());
        break;
      }
      if (!have_prev && cur <= 0) break;  // not on the board where the walk starts
      prev = cur;
      have_prev = true;
    }
  }
  return edges;
}

/// Layout order -> row-major, top-left first (board y up, then x).
std::vector<ImageHole> in_row_major_order(const std::vector<Eigen::Vector2d>& layout,
                                          const std::vector<ImageHole>& holes) {
  std::vector<std::size_t> order(layout.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (std::abs(layout[a].y() - layout[b].y()) > 1e-6) return layout[a].y() > layout[b].y();
    return layout[a].x() < layout[b].x();
  });
  std::vector<ImageHole> sorted;
  for (std::size_t k : order) sorted.push_back(holes[k]);
  return sorted;
}

/// Traces the chosen candidates into det's holes (row-major); false, with det->reason, when
/// one of them does not make a hole.
bool trace_holes(const cv::Mat& f, const std::vector<Candidate>& chosen, const HoleSearch& search,
                 const std::optional<Eigen::Vector2d>& seed_px, const ImageDetectionOptions& options,
                 ImageTargetDetection* det) {
  for (std::size_t h = 0; h < chosen.size(); ++h) {
    const Candidate& c = chosen[h];
    // Algorithm 1 from the hole's centre (the automatic seed) or the clicked seed.
    const Eigen::Vector2i seed =
        seed_px && search.layout.size() == 1
            ? Eigen::Vector2i(seed_px->array().round().cast<int>())
            : Eigen::Vector2i(static_cast<int>(std::lround(c.ellipse.center.x)),
                              static_cast<int>(std::lround(c.ellipse.center.y)));
    ImageHole hole;
    if (!trace_hole(f, c, h, seed, options, &hole, &det->reason)) return false;
    det->holes.push_back(std::move(hole));
  }
  det->holes = in_row_major_order(search.layout, det->holes);
  det->ok = true;
  return true;
}

/// Fraction of the rays that must find the board's edge on a predicted hole's ellipse: less
/// than a found hole needs (0.6), since the layout already puts it there and it must land
/// within half a radius of that place at the size the found pair gives; a bright stripe of
/// the background across the hole takes the rays on both its sides (about half of them).
constexpr double kPredictedHoleSupport = 0.4;

/// The hole a prediction makes, if any: `like`'s ellipse moved to `at` and refined by the
/// board's edge around it (refine_board_hole), kept when enough rays find that edge on its
/// ellipse, it stays within half a radius of `at` at about the expected radius r_px, and
/// the board around it is homogeneous.
std::optional<Candidate> predicted_hole(const cv::Mat& f, const HoleSearch& search, const ImageDetectionOptions& o,
                                        Candidate c, const Eigen::Vector2d& at, double r_px) {
  if (at.x() - 1.8 * r_px < 1 || at.y() - 1.8 * r_px < 1 || at.x() + 1.8 * r_px > f.cols - 2 ||
      at.y() + 1.8 * r_px > f.rows - 2) {
    return std::nullopt;
  }
  c.ellipse.center = cv::Point2f(static_cast<float>(at.x()), static_cast<float>(at.y()));
  c.board_side = true;
  const double support = refine_board_hole(f, o, &c);
  const double a = 0.5 * std::max(c.ellipse.size.width, c.ellipse.size.height);
  const double b = 0.5 * std::min(c.ellipse.size.width, c.ellipse.size.height);
  if (support < kPredictedHoleSupport || !(b > 0) || b / a < o.min_axis_ratio || a > search.max_axis ||
      a < search.min_axis || a < 0.7 * r_px || a > 1.4 * r_px) {
    return std::nullopt;
  }
  if (std::hypot(c.ellipse.center.x - at.x(), c.ellipse.center.y - at.y()) > 0.5 * r_px) return std::nullopt;
  double spread = 0.0;
  if (!levels(f, c.ellipse, &c.inside, &c.outside, &spread)) return std::nullopt;
  const double contrast = std::abs(c.outside - c.inside);
  if (contrast < o.min_contrast || spread > 0.35 * contrast) return std::nullopt;
  c.score = support;
  return c;
}

/// Holes the layout predicts from two found ones, for a board whose other holes neither
/// search gives whole (a bright stripe of the background behind them splits each in two).
/// Each pair of candidates of about one size (of the best 40), taken as two of the layout's
/// holes, fixes a similarity board -> image (board y up, within 45 deg of `up`) whose scale
/// must make both of them holes of the target's radius; it puts the layout's other holes,
/// which predicted_hole checks in the image.
std::vector<Candidate> layout_predicted_candidates(const cv::Mat& f, const HoleSearch& search,
                                                   const std::vector<Candidate>& cand, double radius_m,
                                                   const ImageDetectionOptions& o) {
  std::vector<Candidate> out;
  const std::vector<Eigen::Vector2d>& layout = search.layout;
  const std::size_t k = std::min<std::size_t>(cand.size(), 40);
  const Eigen::Vector2d up = o.up_image.normalized();
  const auto centre = [](const Candidate& c) { return Eigen::Vector2d(c.ellipse.center.x, c.ellipse.center.y); };
  const auto semi_major = [](const Candidate& c) { return 0.5 * std::max(c.ellipse.size.width, c.ellipse.size.height); };
  const auto flip = [](const Eigen::Vector2d& b) { return Eigen::Vector2d(b.x(), -b.y()); };  // image v is down
  const auto taken = [&](const Eigen::Vector2d& q, double r) {
    const std::vector<Candidate>* lists[] = {&cand, &out};
    for (const std::vector<Candidate>* list : lists)
      for (const Candidate& c : *list)
        if ((centre(c) - q).norm() < 0.5 * r) return true;
    return false;
  };
  for (std::size_t i = 0; i < k; ++i) {
    for (std::size_t j = 0; j < k; ++j) {
      const double ai = semi_major(cand[i]), aj = semi_major(cand[j]);
      if (i == j || std::abs(ai - aj) > 0.3 * ai) continue;  // holes of one board: about one size
      const Eigen::Vector2d d_image = centre(cand[j]) - centre(cand[i]);
      for (std::size_t p = 0; p < layout.size(); ++p) {
        for (std::size_t q = 0; q < layout.size(); ++q) {
          if (p == q) continue;
          const Eigen::Vector2d d_board = flip(layout[q] - layout[p]);
          const double scale = d_image.norm() / d_board.norm();  // px per m
          const double r_px = scale * radius_m;
          if (std::min(ai, aj) < 0.7 * r_px || std::max(ai, aj) > 1.4 * r_px) continue;
          const Eigen::Rotation2Dd R(std::atan2(d_image.y(), d_image.x()) - std::atan2(d_board.y(), d_board.x()));
          if ((R * Eigen::Vector2d(0.0, -1.0)).dot(up) <= std::sqrt(0.5)) continue;  // board y up
          for (std::size_t m = 0; m < layout.size(); ++m) {
            if (m == p || m == q) continue;
            const Eigen::Vector2d at = centre(cand[i]) + scale * (R * flip(layout[m] - layout[p]));
            if (taken(at, r_px)) continue;
            if (const auto hole = predicted_hole(f, search, o, cand[i], at, r_px)) out.push_back(*hole);
          }
        }
      }
    }
  }
  return out;
}

}  // namespace

ImageTargetDetection detect_target_in_image(const cv::Mat& image, const core::TargetSpec& target,
                                            const core::PinholeCamera& camera,
                                            const ImageDetectionOptions& options,
                                            std::optional<Eigen::Vector2d> seed_px) {
  if (const std::string err = options.validate(); !err.empty()) {
    throw std::invalid_argument("ImageDetectionOptions: " + err);
  }
  if (!(target.radius_m > 0)) {
    throw std::invalid_argument("TargetSpec: radius_m = " + std::to_string(target.radius_m) + " must be > 0");
  }
  ImageTargetDetection det;
  det.reason = image_problem(image, camera);
  if (!det.reason.empty()) return det;
  const cv::Mat f = normalise_image(image, options.low_percentile, options.high_percentile);
  const double fx = camera.intrinsics().fx;
  HoleSearch search;
  search.max_axis = 1.1 * fx * target.radius_m / options.min_range_m;
  search.min_axis = 0.9 * fx * target.radius_m / options.max_range_m;
  search.layout = target_layout(target);

  if (seed_px) {
    const Eigen::Vector2i s = seed_px->array().round().cast<int>();
    if (s.x() < 0 || s.y() < 0 || s.x() >= f.cols || s.y() >= f.rows) {
      det.reason = "seed (" + std::to_string(s.x()) + ", " + std::to_string(s.y()) + ") outside the image";
      return det;
    }
  }
  std::vector<Candidate> chosen;
  if (choose_candidates(f, target, search, seed_px, options, &chosen, &det.reason) &&
      trace_holes(f, chosen, search, seed_px, options, &det)) {
    det.method = "hole regions";
    return det;
  }
  // The holes as holes of the board: for a textured background behind the holes.
  const std::string first_reason = det.reason;
  det.holes.clear();
  chosen.clear();
  std::vector<Candidate> cand = find_board_hole_candidates(f, search.min_axis, search.max_axis, options);
  if (seed_px) {  // the candidates nearest the seed first, as for the hole search
    sort_nearest_first(*seed_px, &cand);
    const auto dist = [&](const Candidate& c) {
      return std::hypot(c.ellipse.center.x - seed_px->x(), c.ellipse.center.y - seed_px->y());
    };
    // One hole: the seed must be in it (a seed on the background picks no hole).
    if (search.layout.size() == 1) {
      cand.erase(std::remove_if(cand.begin(), cand.end(),
                                [&](const Candidate& c) { return dist(c) > 0.5 * std::min(c.ellipse.size.width, c.ellipse.size.height); }),
                 cand.end());
    }
  }
  std::string why;
  const bool seeded_board = seed_px && search.layout.size() > 1;
  const auto match = [&] {
    return match_layout_image(search.layout, cand, options.up_image.normalized(), &why,
                              seeded_board ? seed_px : std::nullopt,
                              seeded_board ? board_half_extent(target, search.layout) : Eigen::Vector2d::Zero(),
                              target.radius_m, 20);
  };
  std::vector<int> pick = match();
  if (pick.empty() && search.layout.size() > 1 && cand.size() >= 2) {
    // Some holes not whole in either search: the ones the found holes and the layout predict.
    const std::vector<Candidate> predicted = layout_predicted_candidates(f, search, cand, target.radius_m, options);
    if (!predicted.empty()) {
      cand.insert(cand.begin(), predicted.begin(), predicted.end());  // within the match's pool
      pick = match();
    }
  }
  for (int i : pick) chosen.push_back(cand[static_cast<std::size_t>(i)]);
  if (pick.empty() || !trace_holes(f, chosen, search, seed_px, options, &det)) {
    det.ok = false;
    det.holes.clear();
    det.reason = first_reason + "; as holes of the board: " + (pick.empty() ? why : det.reason);
  } else {
    det.method = "holes of the board";
  }
  return det;
}

}  // namespace rgbdt::calib_targets
