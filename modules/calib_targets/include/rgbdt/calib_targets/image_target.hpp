#pragma once
/// \file
/// The circular-hole target in an image: paper Sec. 3.3, Algorithm 1, and beyond.
///
/// Algorithm 1: region growing from a seed over the 8-neighbourhood, a neighbour joins when
/// its intensity is within epsilon of the pixel it is reached from; the boundary is the set
/// of region pixels with a non-region neighbour. Beyond the paper: the seeds are found
/// automatically (dark or bright elliptical regions enclosed by a homogeneous board, of a
/// size consistent with the known radius over a plausible range of distances, in the
/// target's hole layout), the boundary is refined to sub-pixel edge points (crossing of the
/// mid-level between hole and board along the image gradient), and 16-bit thermal images
/// are normalised by percentiles.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "rgbdt/core/camera.hpp"
#include "rgbdt/core/session.hpp"

namespace rgbdt::calib_targets {

struct ImageDetectionOptions {
  /// Algorithm 1's epsilon as a fraction of the hole/board contrast (normalised image).
  /// Lower it for strongly blurred images (the growth must not creep along the ramp).
  double epsilon_fraction = 0.08;
  /// Beyond the paper: a pixel also must be within this fraction of the contrast from the
  /// seed's level, which stops leaks across blurred edges; 0 disables (pure Algorithm 1).
  double seed_guard_fraction = 0.5;
  double low_percentile = 1.0;    ///< normalisation: this percentile maps to 0
  double high_percentile = 99.0;  ///< and this one to 1
  double smoothing_sigma_px = 1.0;  ///< Gaussian applied before region growing
  double min_range_m = 1.0;   ///< plausible target distances, with fx and the radius,
  double max_range_m = 15.0;  ///< bound the size of a hole in the image
  /// Hole/board contrast on the normalised image; low because the percentiles span the whole
  /// scene (sky to ground), the board and the cloth behind the hole may differ little.
  double min_contrast = 0.03;
  double min_axis_ratio = 0.25;  ///< ellipse minor/major axis (board tilt up to ~75 deg)
  /// Sub-pixel search half-length along the gradient [px].
  double edge_search_px = 4.0;
  /// Image direction of "up" on the board, to order the holes (row-major, top-left first).
  Eigen::Vector2d up_image = Eigen::Vector2d(0.0, -1.0);

  /// Empty when usable, else the reason naming the value.
  std::string validate() const;
};

struct ImageHole {
  std::vector<Eigen::Vector2i> boundary_px;     ///< Algorithm 1 boundary pixels
  std::vector<Eigen::Vector2d> edge_points_px;  ///< sub-pixel edge points of the hole
  Eigen::Vector2d center_px = Eigen::Vector2d::Zero();  ///< centre of the fitted ellipse
  cv::RotatedRect ellipse;                      ///< ellipse fitted to the edge points
  bool dark = true;       ///< the hole is darker than the board
  double contrast = 0.0;  ///< |board - hole| on the normalised image
};

struct ImageTargetDetection {
  bool ok = false;
  std::string reason;
  std::vector<ImageHole> holes;  ///< in layout order (row-major, top-left first)
  /// How the holes were found: "hole regions" (homogeneous holes, Algorithm 1) or "holes of
  /// the board" (the board's edge around holes whose background is textured).
  std::string method;
};

/// Detects the target's hole(s). image: 8U or 16U, 1 or 3 channels, of the camera's size.
/// With a seed on a single-hole target, the hole candidate containing it is taken (else
/// Algorithm 1 grows from it); on a multi-hole target a seed anywhere on the board picks
/// the board whose holes match the layout with the seed on the board. Without a seed the
/// holes are found automatically. Never throws for bad images (ok = false and reason); throws
/// std::invalid_argument for invalid options or target.
ImageTargetDetection detect_target_in_image(const cv::Mat& image, const core::TargetSpec& target,
                                            const core::PinholeCamera& camera,
                                            const ImageDetectionOptions& options = {},
                                            std::optional<Eigen::Vector2d> seed_px = {});

/// Algorithm 1 exactly: region growing from `seed` on a single-channel float image; a
/// neighbour joins when |I(neighbour) - I(point)| <= epsilon (and, when seed_guard > 0,
/// |I(neighbour) - I(seed)| <= seed_guard). Returns the boundary pixels; `region` (CV_8U,
/// 255 = region) receives the grown region. Stops with an empty result when the region
/// exceeds max_pixels.
std::vector<Eigen::Vector2i> grow_region(const cv::Mat& image_f32, const Eigen::Vector2i& seed,
                                         double epsilon, double seed_guard, cv::Mat* region,
                                         std::size_t max_pixels);

/// Grey float image in [0, 1] (values outside the percentiles are clipped), from 8U/16U,
/// 1 or 3 channels.
cv::Mat normalise_image(const cv::Mat& image, double low_percentile, double high_percentile);

}  // namespace rgbdt::calib_targets
