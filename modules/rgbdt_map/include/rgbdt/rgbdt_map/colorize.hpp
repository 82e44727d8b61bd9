#pragma once
/// \file
/// Colouring LIDAR points from RGB and thermal images (paper Sec. 5: "we apply the computed
/// extrinsic parameters and project them on to the RGB and thermal images"), with two
/// things the paper leaves out:
///   - motion compensation: a point measured at t_p and an image taken at t_i are related
///     by T_camera_lidar * T_world_lidar(t_i)^-1 * T_world_lidar(t_p) when a trajectory is known;
///   - occlusion: the camera sits beside the LIDAR, so it does not see everything the LIDAR
///     sees. A point hidden from the camera by nearer surfaces must not take their colour.
///     The scan lines of the cloud are meshed (neighbouring beams of neighbouring scans),
///     the mesh is rasterised into a depth buffer seen from the camera, and a point is
///     visible only if its depth is within a tolerance of the buffer's surface. Meshing
///     rather than splatting points keeps surfaces seen at grazing angles (the ground)
///     visible: a surface never occludes itself, however steep its depth gradient.
/// Along depth edges the LIDAR did not sample where exactly the near object ends: it may
/// reach up to the next rays, which found the far surface. That largest possible extent
/// (the edge triangle with its far vertices pulled back along their LIDAR rays to the near
/// range) is projected into the camera and occludes; far samples behind it stay
/// uncoloured, those the camera sees beside it (parallax) keep their colour.
/// Points outside the image, behind the camera or occluded keep no colour and carry a
/// status saying why; they are never painted black.
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/camera.hpp"
#include "rgbdt/rgbdt_map/trajectory.hpp"

namespace rgbdt::rgbdt_map {

/// Why a point has, or has not, a colour from one camera.
enum class ColorStatus : std::uint8_t {
  kColored = 0,   ///< visible; the colour / temperature is valid
  kNoImage,       ///< no image of that camera was available for the point
  kBehindCamera,  ///< depth <= min_depth_m in the camera frame
  kOutsideImage,  ///< projects outside the image
  kOccluded,      ///< hidden from the camera by a nearer surface
  kNoTemperature, ///< visible, but the radiometry gives no temperature for its counts
};
const char* to_string(ColorStatus status);

/// One camera of the rig as the colouring needs it.
struct MappedCamera {
  core::PinholeCamera camera;
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();  ///< LIDAR -> camera
};

struct ColorizeOptions {
  /// A point is visible when depth <= surface depth + depth_tolerance_m +
  /// depth_tolerance_ratio * depth + 0.71 cell * its surface's depth gradient [m/cell]
  /// (the point lies up to 0.71 cell from the cell centre it is compared at, which matters
  /// on steep, grazing surfaces such as the far ground). Raise both with noisy ranges.
  double depth_tolerance_m = 0.05;     ///< [m]
  double depth_tolerance_ratio = 0.03;  ///< [-]
  /// The z-buffer is the image downscaled by an integer factor so it is at most this wide;
  /// 800 keeps a 1288 px RGB image's buffer at 644 px (cells of 2 px) and a 640 px thermal
  /// image's at full resolution. Occluding edges are drawn one margin (0.75 cell) wider,
  /// so coarser cells cost visible points beside edges: 400 (4 px RGB cells) coloured
  /// 97.6 % of the truly visible points of a simulated street, 800 98.2 %.
  int zbuffer_max_width_px = 800;
  /// Timing of the 2D scanner (rgbdt/core/tilt_rig.hpp) used to find the same beam in
  /// neighbouring scan lines from the per-point time `t`.
  double scan_period_s = 0.025;     ///< [s]
  int steps_per_revolution = 1440;  ///< beam period = scan_period_s / steps_per_revolution
  /// A mesh triangle spans a depth edge rather than a surface when its plane makes less
  /// than edge_angle_deg with the LIDAR's ray, or when its far vertex is deeper than
  /// (1 + discontinuity_ratio) times its near vertex (+ depth_tolerance_m). Edge triangles
  /// occlude with the near object's largest possible extent (see the file comment);
  /// triangles the camera sees from their other side (parallax folds) are drawn flat at
  /// their near depth.
  /// The ground seen at a grazing angle h / r stays a surface while that angle exceeds
  /// edge_angle_deg: with 3 deg, up to 19 m for a sensor 1 m above the ground. The ratio
  /// rule only catches what the angle misses (wide gaps between scan lines); a low ratio
  /// turns the far ground into edges too (0.5 cost 3 % of the visible points of a yard).
  double edge_angle_deg = 3.0;     ///< [deg]
  double discontinuity_ratio = 2.0;  ///< [-]
  /// Triangles wider or taller than this in the image are dropped (wrap-arounds, objects
  /// touching the sensor). [px]
  double max_triangle_extent_px = 400.0;
  /// Clouds without ring/t cannot be meshed: each point then covers a square of
  /// (2 r + 1)^2 z-buffer cells.
  int fallback_splat_radius_cells = 1;
  double min_depth_m = 0.05;  ///< nearer points count as behind the camera [m]
  std::string validate() const;
};

/// Where each point of a cloud falls in one image, and whether the camera sees it.
struct CameraProjection {
  std::vector<Eigen::Vector2f> pixel_px;  ///< valid where status == kColored
  std::vector<float> depth_m;             ///< depth in the camera frame [m]
  std::vector<ColorStatus> status;        ///< kColored = visible
  std::size_t visible = 0;
  bool meshed = false;                    ///< true when the scan-line mesh was used
  /// The camera's image size [px] the pixels refer to (0 when unknown): sampling an image
  /// of another size throws instead of reading the wrong pixels.
  int image_width = 0, image_height = 0;
};

/// Projects every point of `cloud` into `camera` at the image's time and decides its
/// visibility. Point i was measured at cloud_time_s + cloud[i].t; with a non-null,
/// non-empty `trajectory` (T_world_lidar) it is first moved into the LIDAR frame at
/// image_time_s. `has_ring_and_t` says whether the ring/t fields are real (see
/// cloud::LoadedCloud); without them the fallback point splats are used.
/// Thread-safe; each calling thread keeps its scratch buffers between calls (42 bytes per
/// point of its largest cloud plus one float per z-buffer cell: ~2.6 MB for a 31k-point tilt).
CameraProjection project_with_occlusion(const cloud::Cloud& cloud, bool has_ring_and_t, double cloud_time_s,
                                        const MappedCamera& camera, double image_time_s,
                                        const Trajectory* trajectory, const ColorizeOptions& options = {});

struct RgbColors {
  std::vector<std::array<std::uint8_t, 3>> rgb;  ///< red green blue; valid where status == kColored
  std::vector<ColorStatus> status;
  std::size_t colored = 0;
};
/// Bilinear sampling of an 8-bit BGR (OpenCV order) or grey image at the visible points.
/// Throws std::invalid_argument if the image type or size does not match the camera.
RgbColors sample_rgb(const CameraProjection& projection, const cv::Mat& image);

struct Temperatures {
  std::vector<float> temperature_k;  ///< [K]; NaN where status != kColored
  std::vector<ColorStatus> status;
  std::size_t colored = 0;
};
/// Temperature of the visible points: each of the four neighbouring pixels' counts goes
/// through `lut_k` (65536 entries, counts -> kelvin) and the results are interpolated
/// bilinearly (interpolating temperatures, not counts, stays right for non-linear
/// radiometry). `counts` is CV_16UC1 (raw counts) or CV_8UC1. A point whose neighbouring
/// counts have no temperature (NaN in the LUT: outside a Planck curve's domain) gets
/// kNoTemperature. Throws std::invalid_argument if the image type or size does not match
/// the camera.
Temperatures sample_temperature(const CameraProjection& projection, const cv::Mat& counts,
                                const std::vector<float>& lut_k);

/// Statuses for a cloud that has no image of a camera at all.
std::vector<ColorStatus> no_image_status(std::size_t points);

/// The 65536-entry look-up table of a linear radiometric map: K = offset_k + kelvin_per_count * counts.
std::vector<float> linear_thermal_lut(double kelvin_per_count, double offset_k);

}  // namespace rgbdt::rgbdt_map
