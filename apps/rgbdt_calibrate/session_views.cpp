#include "session_views.hpp"

#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "rgbdt/calib_targets/image_target.hpp"
#include "rgbdt/calib_targets/lidar_target.hpp"
#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::calibrate {

extrinsics::TargetView make_target_view(const calib_targets::LidarTargetDetection& lidar,
                                        const calib_targets::ImageTargetDetection& image,
                                        const core::TargetSpec& target, const cv::Size& image_size,
                                        const std::string& name) {
  extrinsics::TargetView v;
  v.name = name;
  v.radius_m = target.radius_m;
  // The image's own size: align_edges rejects a view whose image does not match the camera.
  v.image_width = image_size.width;
  v.image_height = image_size.height;
  // Eq. (2) needs no hole correspondence: all circles against all image edges.
  for (const auto& h : lidar.holes)
    v.lidar_circle_points.insert(v.lidar_circle_points.end(), h.circle_points.begin(), h.circle_points.end());
  for (const auto& h : image.holes)
    v.image_edge_points_px.insert(v.image_edge_points_px.end(), h.edge_points_px.begin(), h.edge_points_px.end());
  // The closed-form guess pairs holes, which both detectors order the same way; only when
  // both found every hole.
  if (lidar.holes.size() == image.holes.size()) {
    for (size_t k = 0; k < lidar.holes.size(); ++k) {
      v.lidar_centers.push_back(lidar.holes[k].center);
      v.lidar_normals.push_back(lidar.holes[k].normal);
      v.image_ellipses.push_back(image.holes[k].ellipse);
    }
  }
  return v;
}

SessionDetections detect_session_views(const core::CalibrationSession& session,
                                       const std::map<std::string, core::PinholeCamera>& cameras,
                                       bool lidar_seeds, bool image_seeds, const Progress& progress,
                                       const StopRequested& stop) {
  SessionDetections result;
  std::map<std::string, CameraViews>& out = result.cameras;
  for (const auto& [name, camera] : cameras) out[name].camera_name = name;
  const size_t n = session.views.size();
  std::size_t kept_image_bytes = 0;  // decoded images kept for the overlays (kOverlayImageBudgetBytes)
  for (size_t i = 0; i < n; ++i) {
    if (stop && stop()) {
      result.stopped = true;
      return result;
    }
    const core::CalibrationView& view = session.views[i];
    const std::string label = "view " + std::to_string(i);
    calib_targets::LidarTargetDetection lidar;
    std::string lidar_note;
    std::size_t cloud_points = 0;
    try {
      const cloud::LoadedCloud loaded = cloud::load_cloud(view.cloud);
      cloud_points = loaded.cloud->size();
      const auto detect = [&](std::optional<Eigen::Vector3d> seed) {
        return calib_targets::detect_target_in_cloud(*loaded.cloud, loaded.has_ring, session.target, {}, seed);
      };
      if (lidar_seeds && view.lidar_seed) {
        lidar = detect(view.lidar_seed);
        if (!lidar.ok) {
          const std::string seeded = lidar.reason;
          lidar = detect({});
          if (lidar.ok) {
            lidar_note = label + ": LIDAR seed: seeded detection failed (" + seeded +
                         "); the automatic detection found the target";
          } else {
            lidar.reason = "seeded detection: " + seeded + "; automatic detection: " + lidar.reason;
            lidar_note = label + ": LIDAR seed: " + lidar.reason;
          }
        }
      } else {
        lidar = detect({});
      }
    } catch (const std::exception& e) {
      lidar = {};
      lidar.reason = std::string("cannot read the cloud: ") + e.what();
    }
    {
      std::ostringstream os;
      os << label << "/" << n << ": LIDAR " << cloud_points << " points: ";
      if (lidar.ok) os << lidar.holes.size() << " hole(s) found";
      else os << "target not found (" << lidar.reason << ")";
      if (lidar.ok && !lidar_note.empty()) os << " (seed failed, automatic detection used)";
      progress(os.str());
    }
    for (const auto& [name, camera] : cameras) {
      CameraViews& cv = out[name];
      if (lidar.ok) ++cv.lidar_found;
      if (!lidar_note.empty()) cv.seed_notes.push_back(lidar_note);
      const auto image_it = view.images.find(name);
      if (image_it == view.images.end()) {
        cv.skipped.push_back(label + ": no " + name + " image in session.yaml");
        continue;
      }
      const cv::Mat image = cv::imread(image_it->second, cv::IMREAD_UNCHANGED);
      if (image.empty()) {
        cv.skipped.push_back(label + ": " + image_it->second +
                             ": cannot read the image (expected an 8- or 16-bit PNG)");
        progress("  " + name + ": cannot read " + image_it->second);
        continue;
      }
      std::optional<Eigen::Vector2d> seed;
      if (const auto s = view.image_seeds.find(name); image_seeds && s != view.image_seeds.end())
        seed = s->second;
      calib_targets::ImageTargetDetection det =
          calib_targets::detect_target_in_image(image, session.target, camera, {}, seed);
      std::string image_note;
      if (!det.ok && seed) {
        const std::string seeded = det.reason;
        det = calib_targets::detect_target_in_image(image, session.target, camera, {}, std::nullopt);
        if (det.ok) {
          image_note = label + ": " + name + " seed: seeded detection failed (" + seeded +
                       "); the automatic detection found the target";
        } else {
          det.reason = "seeded detection: " + seeded + "; automatic detection: " + det.reason;
          image_note = label + ": " + name + " seed: " + det.reason;
        }
        cv.seed_notes.push_back(image_note);
      }
      std::ostringstream os;
      os << "  " << name << ": ";
      if (det.ok) {
        ++cv.image_found;
        os << det.holes.size() << " hole(s) found";
        if (det.method != "hole regions") os << " as " << det.method << " (textured background)";
        if (!image_note.empty()) os << " (seed failed, automatic detection used)";
      } else {
        os << "target not found (" << det.reason << ")";
      }
      progress(os.str());
      if (!det.ok || !lidar.ok) {
        cv.skipped.push_back(label + ": " + (lidar.ok ? name + " image: " + det.reason
                                                      : "LIDAR: " + lidar.reason));
        continue;
      }
      cv.views.push_back(make_target_view(lidar, det, session.target, image.size(), label));
      cv.session_index.push_back(static_cast<int>(i));
      cv.image_paths.push_back(image_it->second);
      const std::size_t bytes = image.total() * image.elemSize();
      const bool keep = kept_image_bytes + bytes <= kOverlayImageBudgetBytes;
      cv.images.push_back(keep ? image : cv::Mat());
      if (keep) kept_image_bytes += bytes;
      std::vector<extrinsics::LidarHoleSigma> sigmas;
      for (const auto& h : lidar.holes) {
        // Too few points to measure: leave the view to the covariance's default (an empty
        // list for the view makes every hole use it).
        if (h.edge_points.size() < 3 || lidar.board_points.size() < 3) {
          sigmas.clear();
          break;
        }
        sigmas.push_back(extrinsics::lidar_hole_sigma(h.edge_points, lidar.board_points, h.center, h.normal,
                                                      session.target.radius_m, h.edge_bias_m,
                                                      lidar.point_spacing_m));
      }
      cv.hole_sigmas.push_back(std::move(sigmas));
      cv.lidar_detections.push_back(lidar);
      cv.lidar_detections.back().board_points.clear();
      for (auto& h : cv.lidar_detections.back().holes) h.edge_points.clear();
    }
    result.views_done = i + 1;
  }
  return result;
}

}  // namespace rgbdt::calibrate
