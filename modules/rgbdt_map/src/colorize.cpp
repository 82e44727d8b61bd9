#include "rgbdt/rgbdt_map/colorize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace rgbdt::rgbdt_map {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
/// Occluding regions at depth edges are rasterised conservatively: cells whose centre lies
/// within this distance outside the region count too (range noise moves the edge samples,
/// and a point is looked up at its nearest cell centre) [z-buffer cells].
constexpr float kEdgeMarginCells = 0.75f;
/// Each near sample on a depth edge also covers a square of half-width kEdgeSplatFraction
/// times its spacing to its neighbours (at least one cell, at most kMaxEdgeSplatCells):
/// insurance for edges the mesh misses (a neighbouring beam without a return leaves no
/// triangle). On a simulated 12 s street a fraction of 0.1 keeps 98 % of the truly
/// visible points coloured; full-spacing squares (0.3, without pulled regions) keep 95 %.
constexpr int kMaxEdgeSplatCells = 12;
constexpr float kEdgeSplatFraction = 0.1f;
/// Farthest a point lies from its nearest z-buffer cell centre [cells].
constexpr float kHalfCellDiagonal = 0.7072f;

/// Depth buffer on a grid of cells `scale` image pixels wide; cell (i, j) is centred on
/// image pixel ((i + 0.5) * scale - 0.5, (j + 0.5) * scale - 0.5).
/// `storage` holds the cells (reused across calls: see Workspace).
struct DepthBuffer {
  int width = 0, height = 0, scale = 1;
  std::vector<float>& depth;
  DepthBuffer(std::vector<float>& storage, int image_width, int image_height, int max_width) : depth(storage) {
    scale = std::max(1, (image_width + max_width - 1) / max_width);
    width = (image_width + scale - 1) / scale;
    height = (image_height + scale - 1) / scale;
    depth.assign(static_cast<std::size_t>(width) * height, kInf);
  }
  float to_cell(float pixel) const { return (pixel + 0.5f) / static_cast<float>(scale) - 0.5f; }
  float& at(int x, int y) { return depth[static_cast<std::size_t>(y) * width + x]; }
  float at(int x, int y) const { return depth[static_cast<std::size_t>(y) * width + x]; }
};

/// Rasterises one triangle (cell coordinates, depths) into the buffer keeping the nearest
/// surface. 1/z is affine in the image of a pinhole camera, so it is interpolated.
/// margin_cells > 0 also covers cells whose centre lies within that distance outside the
/// triangle (conservative rasterisation, used for occluding edges).
void rasterize(DepthBuffer& buffer, const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c,
               float za, float zb, float zc, float margin_cells) {
  float area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
  if (std::abs(area) < 1e-6f) return;
  const float m = margin_cells;
  const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}) - m)));
  const int x1 = std::min(buffer.width - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}) + m)));
  const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}) - m)));
  const int y1 = std::min(buffer.height - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}) + m)));
  if (x0 > x1 || y0 > y1) return;
  const float sign = area > 0 ? 1.0f : -1.0f;
  area = std::abs(area);
  const float inv_area = 1.0f / area;
  // Edge lengths turn edge functions (twice the signed area) into distances [cells].
  const float la = (c - b).norm(), lb = (a - c).norm(), lc = (b - a).norm();
  const float ia = 1.0f / za, ib = 1.0f / zb, ic = 1.0f / zc;
  // Hoisted: through buffer.at() the compiled loop loaded the vector's data pointer again
  // for every cell (perf annotate).
  float* const cells = buffer.depth.data();
  const std::size_t row_cells = static_cast<std::size_t>(buffer.width);
  for (int y = y0; y <= y1; ++y) {
    float* const row = cells + static_cast<std::size_t>(y) * row_cells;
    for (int x = x0; x <= x1; ++x) {
      const float px = static_cast<float>(x), py = static_cast<float>(y);
      const float e0 = sign * ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px));
      const float e1 = sign * ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px));
      const float e2 = area - e0 - e1;
      // A small tolerance closes cracks on edges shared by two triangles.
      const float tol = 1e-3f + m;
      if (e0 < -tol * la || e1 < -tol * lb || e2 < -tol * lc) continue;
      const float w0 = std::clamp(e0 * inv_area, 0.0f, 1.0f);
      const float w1 = std::clamp(e1 * inv_area, 0.0f, 1.0f);
      const float w2 = std::max(0.0f, 1.0f - w0 - w1);
      const float z = 1.0f / (w0 * ia + w1 * ib + w2 * ic);
      float& cell = row[x];
      if (z < cell) cell = z;
    }
  }
}

/// project_with_occlusion's per-point and per-cell buffers, kept per thread between calls.
/// A tilt's buffers take ~2.5 MB: allocated anew on every call, glibc maps them from the
/// kernel and unmaps them on return, and the page faults of touching them again cost a
/// fifth of the call (perf, rgbdt_map_bench's 31k-point tilt). Reused, each call only
/// rewrites them.
struct Workspace {
  std::vector<std::uint8_t> projectable, edge_vertex;
  std::vector<Eigen::Vector3f> q_camera, origin_camera;
  std::vector<Eigen::Vector2f> cell;
  std::vector<float> slope_m_per_cell, footprint, depth_cells;
};

/// Motion between the point's time and the image's time, cached per 0.5 ms bin: at cart
/// speeds (< 5 m/s) that is < 2.5 mm, far below the LIDAR noise.
class MotionCache {
 public:
  MotionCache(const Trajectory& trajectory, double image_time_s)
      : trajectory_(trajectory), T_lidar_world_image_(trajectory.pose_at(image_time_s).inverse()) {}
  /// The bin of time t: T_image_point is the same for every t of one bin.
  static long long bin_of(double t) { return std::llround(t / kBinS); }
  const Eigen::Isometry3d& T_image_point(double t) {
    const long long bin = bin_of(t);
    auto it = cache_.find(bin);
    if (it == cache_.end()) {
      it = cache_.emplace(bin, T_lidar_world_image_ * trajectory_.pose_at(bin * kBinS)).first;
    }
    return it->second;
  }

 private:
  static constexpr double kBinS = 5e-4;
  const Trajectory& trajectory_;
  Eigen::Isometry3d T_lidar_world_image_;
  std::unordered_map<long long, Eigen::Isometry3d> cache_;
};

/// Normalised-coordinate bounds of the image (with margin): distortion polynomials fold
/// far-off-axis points back into the image, so those are rejected before projecting.
struct ImageBounds {
  double x_max = 0.0, y_max = 0.0;
  /// Whether a camera-frame point in front of the camera lies beyond the bounds.
  bool beyond(const Eigen::Vector3f& q) const {
    return std::abs(q.x()) > x_max * q.z() || std::abs(q.y()) > y_max * q.z();
  }
};

ImageBounds image_bounds(const core::PinholeCamera& camera) {
  ImageBounds bounds;
  for (const auto& corner : {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(camera.width() - 0.5, -0.5),
                             Eigen::Vector2d(-0.5, camera.height() - 0.5),
                             Eigen::Vector2d(camera.width() - 0.5, camera.height() - 0.5)}) {
    const Eigen::Vector3d ray = camera.unproject(corner);
    bounds.x_max = std::max(bounds.x_max, std::abs(ray.x()));
    bounds.y_max = std::max(bounds.y_max, std::abs(ray.y()));
  }
  bounds.x_max *= 1.25;
  bounds.y_max *= 1.25;
  return bounds;
}

/// Every point in the camera frame at image time (motion-compensated along the trajectory
/// when there is one): out's depth, pixel and status (behind the camera, outside the image or
/// colored until occlusion is tested) and the workspace's q_camera, origin_camera and
/// projectable.
void project_points(const cloud::Cloud& cloud, double cloud_time_s, const MappedCamera& mapped,
                    double image_time_s, const Trajectory* trajectory,
                    const ColorizeOptions& options, const ImageBounds& bounds, Workspace* workspace,
                    CameraProjection* out) {
  const core::PinholeCamera& camera = mapped.camera;
  const std::size_t n = cloud.size();
  const bool compensate = trajectory != nullptr && !trajectory->empty();
  std::optional<MotionCache> motion;
  if (compensate) motion.emplace(*trajectory, image_time_s);
  const Eigen::Isometry3f T_camera_lidar = mapped.T_camera_lidar.cast<float>();

  // Projection of every point; `projectable` marks points whose pixel may be used as a
  // mesh vertex even if it lands just outside the image.
  std::vector<std::uint8_t>& projectable = workspace->projectable;
  projectable.assign(n, 0);
  std::vector<Eigen::Vector3f>& q_camera = workspace->q_camera;
  q_camera.resize(n);
  // Where the LIDAR was when it measured each point, in the camera frame at image time.
  std::vector<Eigen::Vector3f>& origin_camera = workspace->origin_camera;
  origin_camera.assign(n, T_camera_lidar.translation());
  // A tilt's points come in time order: consecutive points share the motion cache's bin.
  long long cached_bin = std::numeric_limits<long long>::min();
  Eigen::Isometry3f T_camera_point = T_camera_lidar;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = cloud[i];
    Eigen::Vector3f q(p.x, p.y, p.z);
    if (compensate) {
      const double t = cloud_time_s + p.t;
      if (const long long bin = MotionCache::bin_of(t); bin != cached_bin) {
        T_camera_point = T_camera_lidar * motion->T_image_point(t).cast<float>();
        cached_bin = bin;
      }
      q = T_camera_point * q;
      origin_camera[i] = T_camera_point.translation();
    } else {
      q = T_camera_lidar * q;
    }
    out->depth_m[i] = q.z();
    q_camera[i] = q;
    if (!(q.z() > options.min_depth_m)) {
      out->status[i] = ColorStatus::kBehindCamera;
      continue;
    }
    if (bounds.beyond(q)) continue;
    Eigen::Vector2d uv;
    camera.project(q.cast<double>(), &uv);
    out->pixel_px[i] = uv.cast<float>();
    projectable[i] = 1;
    if (camera.in_image(uv, -0.5)) out->status[i] = ColorStatus::kColored;
  }
}

/// Point index per ring and beam position within the scan (-1 where no point is).
using ScanGrid = std::unordered_map<std::uint16_t, std::vector<int>>;

/// Scan-line mesh: vertex (ring, beam position within the scan). Beam k of a scan is
/// measured k * scan_period / steps after the scan starts and scans follow each other
/// every scan_period (rgbdt/core/tilt_rig.hpp), so round(t / beam_period) mod steps is
/// the same for the same beam in every scan.
ScanGrid scan_grid(const cloud::Cloud& cloud, bool has_ring_and_t,
                   const std::vector<std::uint8_t>& projectable, const ColorizeOptions& options) {
  ScanGrid grid;
  const std::size_t n = cloud.size();
  if (has_ring_and_t && n > 0) {
    const int steps = options.steps_per_revolution;
    const double beam_period_s = options.scan_period_s / steps;
    for (std::size_t i = 0; i < n; ++i) {
      if (!projectable[i]) continue;
      const long long k = std::llround(static_cast<double>(cloud[i].t) / beam_period_s);
      const int position = static_cast<int>(((k % steps) + steps) % steps);
      auto& row = grid[cloud[i].ring];
      if (row.empty()) row.assign(steps, -1);
      row[position] = static_cast<int>(i);
    }
  }
  return grid;
}

/// Draws the scan-line mesh's triangles into the depth buffer: surfaces at their own depths
/// (recording each vertex's slope and footprint), depth edges and folds conservatively at
/// their near depth (marking the edges' near vertices).
class MeshRasterizer {
 public:
  MeshRasterizer(const MappedCamera& mapped, const ColorizeOptions& options,
                 const ImageBounds& bounds, const CameraProjection& out, Workspace& workspace,
                 DepthBuffer& buffer)
      : camera_(mapped.camera),
        options_(options),
        bounds_(bounds),
        depth_m_(out.depth_m),
        cell_(workspace.cell),
        q_camera_(workspace.q_camera),
        origin_camera_(workspace.origin_camera),
        edge_vertex_(workspace.edge_vertex),
        slope_m_per_cell_(workspace.slope_m_per_cell),
        footprint_(workspace.footprint),
        buffer_(buffer),
        max_extent_cells_(static_cast<float>(options.max_triangle_extent_px / buffer.scale)),
        jump_ratio_(static_cast<float>(1.0 + options.discontinuity_ratio)),
        jump_m_(static_cast<float>(options.depth_tolerance_m)),
        lidar_origin_(mapped.T_camera_lidar.translation()),
        sin_edge_angle_(std::sin(options.edge_angle_deg * M_PI / 180.0)) {}

  /// Two triangles per quad of neighbouring rings and beams.
  void rasterize(const ScanGrid& grid) const {
    const int steps = options_.steps_per_revolution;
    for (const auto& [ring, row] : grid) {
      const auto next = grid.find(static_cast<std::uint16_t>(ring + 1));
      if (next == grid.end()) continue;
      const std::vector<int>& row2 = next->second;
      for (int k = 0; k + 1 < steps; ++k) {
        const int a = row[k], b = row[k + 1], c = row2[k], d = row2[k + 1];
        const int valid = (a >= 0) + (b >= 0) + (c >= 0) + (d >= 0);
        if (valid < 3) continue;
        if (valid == 4) {
          triangle(a, b, c);
          triangle(b, d, c);
        } else {
          // One corner missing: the other three still bound a piece of surface.
          const int v[4] = {a, b, d, c};
          int t[3], m = 0;
          for (int j = 0; j < 4; ++j) {
            if (v[j] >= 0) t[m++] = v[j];
          }
          triangle(t[0], t[1], t[2]);
        }
      }
    }
  }

 private:
  void triangle(int a, int b, int c) const {
    if (a < 0 || b < 0 || c < 0) return;
    const Eigen::Vector2f& pa = cell_[a];
    const Eigen::Vector2f& pb = cell_[b];
    const Eigen::Vector2f& pc = cell_[c];
    const float w = std::max({pa.x(), pb.x(), pc.x()}) - std::min({pa.x(), pb.x(), pc.x()});
    const float h = std::max({pa.y(), pb.y(), pc.y()}) - std::min({pa.y(), pb.y(), pc.y()});
    if (w > max_extent_cells_ || h > max_extent_cells_) return;
    const float za = depth_m_[a], zb = depth_m_[b], zc = depth_m_[c];
    const float z_near = std::min({za, zb, zc});
    // Seen from the camera, a triangle that turns its other side than it showed the LIDAR
    // is a fold: the camera's parallax moved its far vertices behind the near ones.
    const Eigen::Vector3d qa = q_camera_[a].cast<double>(), qb = q_camera_[b].cast<double>(),
                          qc = q_camera_[c].cast<double>();
    const double side_camera = qa.dot(qb.cross(qc));
    const double side_lidar =
        (qa - lidar_origin_).dot((qb - lidar_origin_).cross(qc - lidar_origin_));
    const bool fold = side_camera * side_lidar < 0.0;
    // A triangle that (nearly) contains the LIDAR's ray spans a depth edge, not a surface.
    const Eigen::Vector3d normal = (qb - qa).cross(qc - qa);
    const Eigen::Vector3d ray = (qa + qb + qc) / 3.0 - lidar_origin_;
    const double normal_norm = normal.norm() * ray.norm();
    const bool along_ray =
        normal_norm <= 0.0 || std::abs(normal.dot(ray)) < sin_edge_angle_ * normal_norm;
    const float z_far = std::max({za, zb, zc});
    const bool jump =
        z_far > z_near + jump_m_ && (along_ray || z_far > z_near * jump_ratio_ + jump_m_);
    if (jump) {
      depth_edge(a, b, c, z_near);
    } else if (fold) {
      // The camera sees the other side of the triangle than the LIDAR did: parallax moved
      // its far vertices behind its near ones, so the surface folds over itself in the
      // image. The nearest depth covers the fold.
      rgbdt_map::rasterize(buffer_, pa, pb, pc, z_near, z_near, z_near, kEdgeMarginCells);
    } else {
      surface(a, b, c);
    }
  }

  /// Depth discontinuity: the near surface ends somewhere between its last samples and
  /// the LIDAR's next rays, which found something farther. It reaches at most those
  /// rays: its largest possible extent is this triangle with the far vertices pulled
  /// back along their own LIDAR rays to the near range. The camera sees that region
  /// shifted against the far samples (parallax), so the region itself is projected and
  /// drawn at the near depth (one margin beyond): far samples behind it stay
  /// uncoloured, far samples beside it are seen past the near object and keep theirs.
  void depth_edge(int a, int b, int c, float z_near) const {
    const int v[3] = {a, b, c};
    float range[3];
    float r_near = kInf;
    for (int j = 0; j < 3; ++j) {
      range[j] = (q_camera_[v[j]] - origin_camera_[v[j]]).norm();
      r_near = std::min(r_near, range[j]);
    }
    float z_flat = z_near;
    Eigen::Vector2f corner[3];
    for (int j = 0; j < 3; ++j) {
      corner[j] = cell_[v[j]];
      if (range[j] <= r_near + jump_m_) continue;
      const Eigen::Vector3f& o = origin_camera_[v[j]];
      const Eigen::Vector3f pulled = o + (q_camera_[v[j]] - o) * (r_near / range[j]);
      if (!(pulled.z() > options_.min_depth_m) || bounds_.beyond(pulled)) {
        continue;  // keeps the far vertex: a larger, still conservative region
      }
      Eigen::Vector2d uv;
      camera_.project(pulled.cast<double>(), &uv);
      corner[j] = Eigen::Vector2f(buffer_.to_cell(static_cast<float>(uv.x())),
                                  buffer_.to_cell(static_cast<float>(uv.y())));
      z_flat = std::min(z_flat, pulled.z());
    }
    rgbdt_map::rasterize(buffer_, corner[0], corner[1], corner[2], z_flat, z_flat, z_flat,
                         kEdgeMarginCells);
    for (int j = 0; j < 3; ++j) {
      if (range[j] <= r_near + jump_m_) edge_vertex_[v[j]] = 1;
    }
  }

  /// A piece of surface at its own depths; records its slope and spacing at its vertices.
  void surface(int a, int b, int c) const {
    const Eigen::Vector2f& pa = cell_[a];
    const Eigen::Vector2f& pb = cell_[b];
    const Eigen::Vector2f& pc = cell_[c];
    const float za = depth_m_[a], zb = depth_m_[b], zc = depth_m_[c];
    rgbdt_map::rasterize(buffer_, pa, pb, pc, za, zb, zc, 0.0f);
    // Depth change per cell of this surface in the image: a point is compared with the
    // buffer at its nearest cell centre, up to 0.71 cells away, and on a steep (grazing)
    // surface such as the far ground that moves the surface's depth by more than the
    // tolerance.
    const Eigen::Vector2f e1 = pb - pa, e2 = pc - pa;
    const float det = e1.x() * e2.y() - e1.y() * e2.x();
    if (std::abs(det) > 1e-6f) {
      const float dz1 = zb - za, dz2 = zc - za;
      const float gx = (dz1 * e2.y() - dz2 * e1.y()) / det;
      const float gy = (dz2 * e1.x() - dz1 * e2.x()) / det;
      const float slope = std::sqrt(gx * gx + gy * gy);
      for (const int v : {a, b, c}) slope_m_per_cell_[v] = std::min(slope_m_per_cell_[v], slope);
    }
    const float spacing = std::max({(pa - pb).norm(), (pb - pc).norm(), (pc - pa).norm()});
    for (const int v : {a, b, c}) footprint_[v] = std::max(footprint_[v], spacing);
  }

  const core::PinholeCamera& camera_;
  const ColorizeOptions& options_;
  const ImageBounds& bounds_;
  const std::vector<float>& depth_m_;
  const std::vector<Eigen::Vector2f>& cell_;
  const std::vector<Eigen::Vector3f>& q_camera_;
  const std::vector<Eigen::Vector3f>& origin_camera_;
  std::vector<std::uint8_t>& edge_vertex_;
  std::vector<float>& slope_m_per_cell_;
  std::vector<float>& footprint_;  // largest neighbour spacing on the vertex's surface [cells]
  DepthBuffer& buffer_;
  const float max_extent_cells_;
  const float jump_ratio_;
  const float jump_m_;
  const Eigen::Vector3d lidar_origin_;
  const double sin_edge_angle_;
};

/// Keeps depth z in the buffer's cells within r of the cell nearest `at`.
void splat(const Eigen::Vector2f& at, int r, float z, DepthBuffer& buffer) {
  const int cx = static_cast<int>(std::lround(at.x()));
  const int cy = static_cast<int>(std::lround(at.y()));
  for (int y = std::max(0, cy - r); y <= std::min(buffer.height - 1, cy + r); ++y) {
    for (int x = std::max(0, cx - r); x <= std::min(buffer.width - 1, cx + r); ++x) {
      float& d = buffer.at(x, y);
      d = std::min(d, z);
    }
  }
}

/// The scan-line mesh drawn into the buffer; then each depth-edge sample's small square.
void draw_mesh(const ScanGrid& grid, const MappedCamera& mapped, const ColorizeOptions& options,
               const ImageBounds& bounds, const CameraProjection& out, Workspace& workspace,
               DepthBuffer& buffer) {
  const std::size_t n = out.depth_m.size();
  const std::vector<Eigen::Vector2f>& cell = workspace.cell;
  std::vector<std::uint8_t>& edge_vertex = workspace.edge_vertex;
  edge_vertex.assign(n, 0);
  // Largest neighbour spacing on the vertex's surface [cells].
  std::vector<float>& footprint = workspace.footprint;
  footprint.assign(n, 0.0f);
  const MeshRasterizer mesh(mapped, options, bounds, out, workspace, buffer);
  mesh.rasterize(grid);
  // Edge samples also cover a small square (kEdgeSplatFraction).
  for (std::size_t i = 0; i < n; ++i) {
    if (!edge_vertex[i]) continue;
    const int r = std::clamp(static_cast<int>(std::ceil(kEdgeSplatFraction * footprint[i])), 1,
                             kMaxEdgeSplatCells);
    splat(cell[i], r, out.depth_m[i], buffer);
  }
}

/// Without a mesh: every projectable point's square of radius r [cells].
void splat_points(const CameraProjection& out, const Workspace& workspace, int r,
                  DepthBuffer& buffer) {
  const std::vector<Eigen::Vector2f>& cell = workspace.cell;
  for (std::size_t i = 0; i < out.depth_m.size(); ++i) {
    if (workspace.projectable[i]) splat(cell[i], r, out.depth_m[i], buffer);
  }
}

/// Marks the coloured points that lie behind the buffer's surface (beyond the tolerance)
/// as occluded; counts the others as visible.
void mark_occluded(const std::vector<Eigen::Vector2f>& cell,
                   const std::vector<float>& slope_m_per_cell, const DepthBuffer& buffer,
                   const ColorizeOptions& options, CameraProjection* out) {
  for (std::size_t i = 0; i < out->status.size(); ++i) {
    if (out->status[i] != ColorStatus::kColored) continue;
    const int cx = std::clamp(static_cast<int>(std::lround(cell[i].x())), 0, buffer.width - 1);
    const int cy = std::clamp(static_cast<int>(std::lround(cell[i].y())), 0, buffer.height - 1);
    const float z = out->depth_m[i];
    const float tolerance =
        static_cast<float>(options.depth_tolerance_m + options.depth_tolerance_ratio * static_cast<double>(z)) +
        (std::isfinite(slope_m_per_cell[i]) ? kHalfCellDiagonal * slope_m_per_cell[i] : 0.0f);
    if (z > buffer.at(cx, cy) + tolerance) {
      out->status[i] = ColorStatus::kOccluded;
    } else {
      ++out->visible;
    }
  }
}

}  // namespace

const char* to_string(ColorStatus status) {
  switch (status) {
    case ColorStatus::kColored:
      return "colored";
    case ColorStatus::kNoImage:
      return "no_image";
    case ColorStatus::kBehindCamera:
      return "behind_camera";
    case ColorStatus::kOutsideImage:
      return "outside_image";
    case ColorStatus::kOccluded:
      return "occluded";
    case ColorStatus::kNoTemperature:
      return "no_temperature";
  }
  return "unknown";
}

std::string ColorizeOptions::validate() const {
  std::ostringstream os;
  if (!(depth_tolerance_m >= 0.0))
    os << "depth_tolerance_m = " << depth_tolerance_m << ", expected >= 0; ";
  if (!(depth_tolerance_ratio >= 0.0))
    os << "depth_tolerance_ratio = " << depth_tolerance_ratio << ", expected >= 0; ";
  if (zbuffer_max_width_px < 8)
    os << "zbuffer_max_width_px = " << zbuffer_max_width_px << ", expected >= 8; ";
  if (!(scan_period_s > 0.0)) os << "scan_period_s = " << scan_period_s << ", expected > 0; ";
  if (steps_per_revolution < 1)
    os << "steps_per_revolution = " << steps_per_revolution << ", expected >= 1; ";
  if (!(max_triangle_extent_px > 0.0))
    os << "max_triangle_extent_px = " << max_triangle_extent_px << ", expected > 0; ";
  if (!(edge_angle_deg >= 0.0 && edge_angle_deg < 90.0))
    os << "edge_angle_deg = " << edge_angle_deg << ", expected in [0, 90); ";
  if (!(discontinuity_ratio > 0.0))
    os << "discontinuity_ratio = " << discontinuity_ratio << ", expected > 0; ";
  if (fallback_splat_radius_cells < 0)
    os << "fallback_splat_radius_cells = " << fallback_splat_radius_cells << ", expected >= 0; ";
  if (!(min_depth_m > 0.0)) os << "min_depth_m = " << min_depth_m << ", expected > 0; ";
  return os.str();
}

CameraProjection project_with_occlusion(const cloud::Cloud& cloud, bool has_ring_and_t,
                                        double cloud_time_s, const MappedCamera& mapped,
                                        double image_time_s, const Trajectory* trajectory,
                                        const ColorizeOptions& options) {
  if (const std::string why = options.validate(); !why.empty()) {
    throw std::invalid_argument("ColorizeOptions: " + why);
  }
  const core::PinholeCamera& camera = mapped.camera;
  const std::size_t n = cloud.size();
  CameraProjection out;
  out.image_width = camera.width();
  out.image_height = camera.height();
  out.pixel_px.assign(n, Eigen::Vector2f::Zero());
  out.depth_m.assign(n, 0.0f);
  out.status.assign(n, ColorStatus::kOutsideImage);

  const ImageBounds bounds = image_bounds(camera);
  thread_local Workspace workspace;
  project_points(cloud, cloud_time_s, mapped, image_time_s, trajectory, options, bounds, &workspace,
                 &out);

  DepthBuffer buffer(workspace.depth_cells, camera.width(), camera.height(),
                     options.zbuffer_max_width_px);
  std::vector<Eigen::Vector2f>& cell = workspace.cell;
  cell.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    cell[i] =
        Eigen::Vector2f(buffer.to_cell(out.pixel_px[i].x()), buffer.to_cell(out.pixel_px[i].y()));
  }

  const ScanGrid grid = scan_grid(cloud, has_ring_and_t, workspace.projectable, options);
  // Gentlest depth gradient among the surface triangles around each point [m/cell]: the
  // gentlest, so that a triangle bridging an unflagged depth step cannot loosen the test.
  std::vector<float>& slope_m_per_cell = workspace.slope_m_per_cell;
  slope_m_per_cell.assign(n, kInf);
  out.meshed = grid.size() >= 2;
  if (out.meshed) {
    draw_mesh(grid, mapped, options, bounds, out, workspace, buffer);
  } else {
    splat_points(out, workspace, options.fallback_splat_radius_cells, buffer);
  }

  mark_occluded(cell, slope_m_per_cell, buffer, options, &out);
  return out;
}

namespace {

// Pixels projected for one image size address other scene points in an image of another
// size: refuse rather than colour from the wrong place.
void check_image_size(const char* function, const CameraProjection& projection, const cv::Mat& image) {
  if (projection.image_width == 0 && projection.image_height == 0) return;
  if (image.cols != projection.image_width || image.rows != projection.image_height) {
    throw std::invalid_argument(std::string(function) + ": image is " + std::to_string(image.cols) + "x" +
                                std::to_string(image.rows) + " px, expected the camera's " +
                                std::to_string(projection.image_width) + "x" +
                                std::to_string(projection.image_height) + " px");
  }
}

}  // namespace

RgbColors sample_rgb(const CameraProjection& projection, const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1)) {
    throw std::invalid_argument("sample_rgb: expected an 8-bit BGR or grey image, got type " +
                                std::to_string(image.type()));
  }
  check_image_size("sample_rgb", projection, image);
  const std::size_t n = projection.status.size();
  RgbColors out;
  out.rgb.assign(n, {0, 0, 0});
  out.status = projection.status;
  const int w = image.cols, h = image.rows;
  const int channels = image.channels();
  for (std::size_t i = 0; i < n; ++i) {
    if (out.status[i] != ColorStatus::kColored) continue;
    const float u = std::clamp(projection.pixel_px[i].x(), 0.0f, static_cast<float>(w - 1));
    const float v = std::clamp(projection.pixel_px[i].y(), 0.0f, static_cast<float>(h - 1));
    const int x0 = static_cast<int>(u), y0 = static_cast<int>(v);
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    const float fx = u - x0, fy = v - y0;
    const std::uint8_t* r0 = image.ptr<std::uint8_t>(y0);
    const std::uint8_t* r1 = image.ptr<std::uint8_t>(y1);
    for (int c = 0; c < 3; ++c) {
      const int ch = channels == 3 ? c : 0;
      const float value = (1 - fy) * ((1 - fx) * r0[x0 * channels + ch] + fx * r0[x1 * channels + ch]) +
                          fy * ((1 - fx) * r1[x0 * channels + ch] + fx * r1[x1 * channels + ch]);
      // OpenCV stores blue first; the output is red green blue.
      out.rgb[i][channels == 3 ? 2 - c : c] = static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0f, 255.0f)));
    }
    ++out.colored;
  }
  return out;
}

Temperatures sample_temperature(const CameraProjection& projection, const cv::Mat& counts,
                                const std::vector<float>& lut_k) {
  if (lut_k.size() != 65536) {
    throw std::invalid_argument("sample_temperature: LUT has " + std::to_string(lut_k.size()) +
                                " entries, expected 65536");
  }
  if (counts.empty() || counts.channels() != 1 || (counts.depth() != CV_16U && counts.depth() != CV_8U)) {
    throw std::invalid_argument("sample_temperature: expected a 16-bit or 8-bit single-channel image, got type " +
                                std::to_string(counts.type()));
  }
  check_image_size("sample_temperature", projection, counts);
  const std::size_t n = projection.status.size();
  Temperatures out;
  out.temperature_k.assign(n, std::numeric_limits<float>::quiet_NaN());
  out.status = projection.status;
  const int w = counts.cols, h = counts.rows;
  const bool wide = counts.depth() == CV_16U;
  auto value = [&](int x, int y) {
    return lut_k[wide ? counts.at<std::uint16_t>(y, x) : counts.at<std::uint8_t>(y, x)];
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (out.status[i] != ColorStatus::kColored) continue;
    const float u = std::clamp(projection.pixel_px[i].x(), 0.0f, static_cast<float>(w - 1));
    const float v = std::clamp(projection.pixel_px[i].y(), 0.0f, static_cast<float>(h - 1));
    const int x0 = static_cast<int>(u), y0 = static_cast<int>(v);
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    const float fx = u - x0, fy = v - y0;
    const float t = (1 - fy) * ((1 - fx) * value(x0, y0) + fx * value(x1, y0)) +
                    fy * ((1 - fx) * value(x0, y1) + fx * value(x1, y1));
    if (std::isnan(t)) {
      out.status[i] = ColorStatus::kNoTemperature;
      continue;
    }
    out.temperature_k[i] = t;
    ++out.colored;
  }
  return out;
}

std::vector<ColorStatus> no_image_status(std::size_t points) {
  return std::vector<ColorStatus>(points, ColorStatus::kNoImage);
}

std::vector<float> linear_thermal_lut(double kelvin_per_count, double offset_k) {
  if (!std::isfinite(kelvin_per_count) || !std::isfinite(offset_k) || kelvin_per_count <= 0.0) {
    throw std::invalid_argument("linear_thermal_lut: kelvin_per_count = " + std::to_string(kelvin_per_count) +
                                ", offset_k = " + std::to_string(offset_k) +
                                ", expected finite values and kelvin_per_count > 0");
  }
  std::vector<float> lut(65536);
  for (std::size_t c = 0; c < lut.size(); ++c) {
    lut[c] = static_cast<float>(offset_k + kelvin_per_count * static_cast<double>(c));
  }
  return lut;
}

}  // namespace rgbdt::rgbdt_map
