#pragma once
// The bodies of the contract-reader fuzz targets, shared by the libFuzzer programs and by
// the gtest that replays the kept corpora. Each returns 1 when the reader accepted the
// input and 0 when it refused it with rgbdt::core::Error or std::invalid_argument; any
// other exception escapes (a finding), and a broken invariant of an accepted input aborts.
#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "rgbdt/core/camera_info.hpp"
#include "rgbdt/core/error.hpp"
#include "rgbdt/core/extrinsics.hpp"
#include "rgbdt/core/image_header.hpp"
#include "rgbdt/core/session.hpp"
#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/core/time_index.hpp"

namespace rgbdt::core::fuzz {

// Paths in fuzzed documents resolve below a folder that does not exist.
inline const char* kFuzzFolder = "/nonexistent-rgbdt-fuzz";

template <typename Fn>
int refused_or(Fn&& fn) {
  try {
    return fn();
  } catch (const Error&) {
    return 0;
  } catch (const std::invalid_argument&) {
    return 0;
  }
}

inline std::string text_of(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

inline int camera_info_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const CameraIntrinsics c = parse_camera_info(text_of(data, size), "fuzz.yaml");
    if (!c.validate().empty()) std::abort();
    if (!(c.cx >= 0 && c.cx <= c.width && c.cy >= 0 && c.cy <= c.height)) std::abort();
    // What the reader accepts, the writer writes and the reader reads back the same.
    const CameraIntrinsics again = parse_camera_info(format_camera_info(c), "again.yaml");
    if (again.fx != c.fx || again.cx != c.cx || again.distortion != c.distortion) std::abort();
    return 1;
  });
}

inline int extrinsics_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const std::string text = text_of(data, size);
    const Extrinsics e = parse_extrinsics(text, "fuzz.yaml");
    if (!e.T_parent_child.matrix().allFinite()) std::abort();
    if (e.covariance && !e.covariance->allFinite()) std::abort();
    const Extrinsics again = parse_extrinsics(format_extrinsics(e), "again.yaml");
    if (rotation_error_rad(again.T_parent_child, e.T_parent_child) > 1e-6 ||
        translation_error_m(again.T_parent_child, e.T_parent_child) > 1e-6 * (1 + e.T_parent_child.translation().norm())) {
      std::abort();
    }
    // The camera-LIDAR reading either refuses or returns a camera parent and a LIDAR child.
    refused_or([&] {
      const Extrinsics cl = parse_extrinsics(text, "fuzz.yaml", ExtrinsicsFrames{});
      if (!is_lidar_frame(cl.child_frame) || is_lidar_frame(cl.parent_frame)) std::abort();
      return 1;
    });
    return 1;
  });
}

inline int tilt_rig_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const TiltRig rig = parse_tilt_rig(text_of(data, size), "fuzz.yaml");
    if (!rig.scanner.validate().empty() || !rig.motor.validate().empty()) std::abort();
    if (!rig.T_axis_scanner.matrix().allFinite()) std::abort();
    return 1;
  });
}

inline int time_index_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const auto rows = parse_time_index(text_of(data, size), std::string(kFuzzFolder) + "/index.csv");
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (!std::isfinite(rows[i].time_s) || rows[i].file.empty()) std::abort();
      if (i > 0 && rows[i].time_s < rows[i - 1].time_s) std::abort();
    }
    return 1;
  });
}

inline int calibration_session_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const CalibrationSession s =
        parse_calibration_session(text_of(data, size), std::string(kFuzzFolder) + "/session.yaml");
    if (!(s.target.radius_m > 0 && s.target.radius_m <= 5) || s.views.empty()) std::abort();
    for (const auto& [name, cam] : s.cameras) {
      if (!is_valid_camera_name(name)) std::abort();
    }
    for (const auto& v : s.views) {
      for (const auto& [cam, file] : v.images) {
        if (!s.cameras.count(cam)) std::abort();
      }
      for (const auto& [cam, px] : v.image_seeds) {
        if (!px.allFinite() || !s.cameras.count(cam)) std::abort();
      }
    }
    return 1;
  });
}

inline int mapping_session_input(const std::uint8_t* data, std::size_t size) {
  return refused_or([&] {
    const MappingSession s =
        parse_mapping_session(text_of(data, size), std::string(kFuzzFolder) + "/session.yaml");
    if (s.lidar.rawlog.empty() && s.lidar.clouds.empty()) std::abort();
    for (const auto& [name, cam] : s.cameras) {
      if (!is_valid_camera_name(name) || cam.frames.empty()) std::abort();
      if (cam.radiometry) {
        for (const auto& [k, v] : cam.radiometry->parameters) {
          if (!std::isfinite(v)) std::abort();
        }
      }
    }
    return 1;
  });
}

// read_image_header reads from a path: the bytes go into an in-memory file (memfd) read
// through /proc/self/fd.
inline int image_header_input(const std::uint8_t* data, std::size_t size) {
  const int fd = ::memfd_create("image_header_fuzz", 0);
  if (fd < 0) std::abort();
  std::size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd, data + written, size - written);
    if (n <= 0) std::abort();
    written += static_cast<std::size_t>(n);
  }
  const int accepted = refused_or([&] {
    const ImageHeader h = read_image_header("/proc/self/fd/" + std::to_string(fd));
    if (h.width < 1 || h.width > kMaxImageSide || h.height < 1 || h.height > kMaxImageSide) {
      std::abort();
    }
    if (h.channels < 1 || h.channels > 4 || (h.format != "png" && h.format != "jpeg")) std::abort();
    const std::uint64_t bytes = std::uint64_t(h.width) * std::uint64_t(h.height) *
                                std::uint64_t(h.channels) * std::uint64_t(h.bit_depth > 8 ? 2 : 1);
    if (bytes > kMaxImageBytes) std::abort();
    return 1;
  });
  ::close(fd);
  return accepted;
}

}  // namespace rgbdt::core::fuzz
