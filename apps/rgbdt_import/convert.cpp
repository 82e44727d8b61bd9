#include "convert.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "rgbdt/core/error.hpp"

namespace rgbdt::import {
namespace {

std::string where(const bag::MessageContext& context) {
  return "topic " + context.topic + ", message " + std::to_string(context.index);
}

struct EncodingInfo {
  int type;         // OpenCV type of the stored pixels
  int bayer = -1;   // cvtColor code for Bayer patterns, -1 otherwise
  int to_bgr = -1;  // cvtColor code to BGR for colour orders other than BGR
};

bool encoding_info(const std::string& encoding, EncodingInfo& info) {
  // ROS names the Bayer pattern from the top-left pixel; OpenCV from the second row's second
  // and third pixels, so ROS rggb is OpenCV's BayerBG.
  if (encoding == "mono8" || encoding == "8UC1")
    info = {CV_8UC1};
  else if (encoding == "mono16" || encoding == "16UC1")
    info = {CV_16UC1};
  else if (encoding == "bgr8" || encoding == "8UC3")
    info = {CV_8UC3};
  else if (encoding == "rgb8")
    info = {CV_8UC3, -1, cv::COLOR_RGB2BGR};
  else if (encoding == "bgra8")
    info = {CV_8UC4, -1, cv::COLOR_BGRA2BGR};
  else if (encoding == "rgba8")
    info = {CV_8UC4, -1, cv::COLOR_RGBA2BGR};
  else if (encoding == "bayer_rggb8")
    info = {CV_8UC1, cv::COLOR_BayerBG2BGR};
  else if (encoding == "bayer_bggr8")
    info = {CV_8UC1, cv::COLOR_BayerRG2BGR};
  else if (encoding == "bayer_gbrg8")
    info = {CV_8UC1, cv::COLOR_BayerGR2BGR};
  else if (encoding == "bayer_grbg8")
    info = {CV_8UC1, cv::COLOR_BayerGB2BGR};
  else
    return false;
  return true;
}

void put_text_header(std::ostringstream& os, const PcdCloud& cloud) {
  std::string fields = "x y z", sizes = "4 4 4", types = "F F F", counts = "1 1 1";
  if (!cloud.intensity.empty())
    fields += " intensity", sizes += " 4", types += " F", counts += " 1";
  if (!cloud.ring.empty()) fields += " ring", sizes += " 2", types += " U", counts += " 1";
  if (!cloud.t.empty()) fields += " t", sizes += " 4", types += " F", counts += " 1";
  os << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
     << "FIELDS " << fields << "\nSIZE " << sizes << "\nTYPE " << types << "\nCOUNT " << counts
     << "\nWIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
     << "\nDATA binary\n";
}

}  // namespace

bool is_supported_encoding(const std::string& encoding) {
  EncodingInfo info{};
  return encoding_info(encoding, info);
}

cv::Mat image_to_mat(const bag::Image& image, const bag::MessageContext& context) {
  EncodingInfo info{};
  if (!encoding_info(image.encoding, info)) {
    throw core::Error(where(context),
                      "image encoding '" + image.encoding +
                          "' is not supported (expected mono8, mono16, 8UC1, 16UC1, rgb8, bgr8, "
                          "rgba8, bgra8 or bayer_{rggb,bggr,gbrg,grbg}8)");
  }
  const std::uint64_t row_bytes = std::uint64_t{image.width} * CV_ELEM_SIZE(info.type);
  if (image.width == 0 || image.height == 0 || image.width > core::kMaxImageSide ||
      image.height > core::kMaxImageSide) {
    throw core::Error(where(context), "image size " + std::to_string(image.width) + "x" +
                                          std::to_string(image.height) + " is outside 1.." +
                                          std::to_string(core::kMaxImageSide));
  }
  if (image.step < row_bytes) {
    throw core::Error(where(context), "image step " + std::to_string(image.step) +
                                          " is smaller than a row of " + image.encoding + " (" +
                                          std::to_string(row_bytes) + " bytes)");
  }
  if (image.data.size() < std::uint64_t{image.step} * image.height) {
    throw core::Error(where(context), "image data has " + std::to_string(image.data.size()) +
                                          " bytes, expected height * step = " +
                                          std::to_string(std::uint64_t{image.step} * image.height));
  }
  const cv::Mat view(static_cast<int>(image.height), static_cast<int>(image.width), info.type,
                     const_cast<std::uint8_t*>(image.data.data()), image.step);
  cv::Mat out;
  if (info.bayer >= 0) {
    cv::cvtColor(view, out, info.bayer);
  } else if (info.to_bgr >= 0) {
    cv::cvtColor(view, out, info.to_bgr);
  } else {
    out = view.clone();
  }
  // Big-endian 16-bit data (is_bigendian) is swapped to the host's order.
  if (out.depth() == CV_16U && image.is_bigendian) {
    for (int r = 0; r < out.rows; ++r) {
      auto* row = out.ptr<std::uint16_t>(r);
      for (int c = 0; c < out.cols * out.channels(); ++c) {
        row[c] = static_cast<std::uint16_t>((row[c] >> 8) | (row[c] << 8));
      }
    }
  }
  return out;
}

cv::Mat compressed_to_mat(const bag::CompressedImage& image, const bag::MessageContext& context) {
  std::string format = image.format;
  std::transform(format.begin(), format.end(), format.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool jpeg =
      format.find("jpeg") != std::string::npos || format.find("jpg") != std::string::npos;
  const bool png = format.find("png") != std::string::npos;
  if ((!jpeg && !png) || format.find("compresseddepth") != std::string::npos) {
    throw core::Error(where(context), "compressed image format '" + image.format +
                                          "' is not supported (expected jpeg or png)");
  }
  if (image.data.empty()) throw core::Error(where(context), "compressed image has no data");
  const cv::Mat bytes(1, static_cast<int>(image.data.size()), CV_8UC1,
                      const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat out = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  if (out.empty()) {
    throw core::Error(where(context), "compressed image (" + image.format + ", " +
                                          std::to_string(image.data.size()) +
                                          " bytes) does not decode");
  }
  return out;
}

PcdCloud to_pcd_cloud(const bag::CloudPoints& points, std::int64_t stamp_ns) {
  PcdCloud out;
  const bool has_time = !points.time_ns.empty();
  std::vector<std::size_t> kept;
  kept.reserve(points.xyz.size());
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  for (std::size_t i = 0; i < points.xyz.size(); ++i) {
    const auto& p = points.xyz[i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
    // Drivers (Hesai, Ouster) mark a missing return as the origin: never a measured point.
    if (p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0) continue;
    kept.push_back(i);
    if (has_time) first = std::min(first, points.time_ns[i]);
  }
  out.first_time_ns = has_time && !kept.empty() ? first : stamp_ns;
  out.xyz.reserve(3 * kept.size());
  for (std::size_t i : kept) {
    for (int k = 0; k < 3; ++k) out.xyz.push_back(static_cast<float>(points.xyz[i][k]));
  }
  if (!points.intensity.empty()) {
    for (std::size_t i : kept) out.intensity.push_back(points.intensity[i]);
  }
  if (!points.ring.empty()) {
    for (std::size_t i : kept) out.ring.push_back(points.ring[i]);
  }
  if (has_time) {
    for (std::size_t i : kept) {
      out.t.push_back(static_cast<float>(double(points.time_ns[i] - out.first_time_ns) * 1e-9));
    }
  }
  return out;
}

void append_cloud(PcdCloud& into, const PcdCloud& more) {
  if (into.size() == 0) {
    into = more;
    return;
  }
  const bool intensity = !into.intensity.empty() && !more.intensity.empty();
  const bool ring = !into.ring.empty() && !more.ring.empty();
  const bool t = !into.t.empty() && !more.t.empty();
  into.xyz.insert(into.xyz.end(), more.xyz.begin(), more.xyz.end());
  if (intensity)
    into.intensity.insert(into.intensity.end(), more.intensity.begin(), more.intensity.end());
  else
    into.intensity.clear();
  if (ring)
    into.ring.insert(into.ring.end(), more.ring.begin(), more.ring.end());
  else
    into.ring.clear();
  if (t) {
    const double shift_s = double(more.first_time_ns - into.first_time_ns) * 1e-9;
    for (float v : more.t) into.t.push_back(static_cast<float>(v + shift_s));
  } else {
    into.t.clear();
  }
}

std::string format_pcd(const PcdCloud& cloud) {
  std::ostringstream os;
  put_text_header(os, cloud);
  std::string out = os.str();
  const std::size_t point_bytes = 12 + (cloud.intensity.empty() ? 0 : 4) +
                                  (cloud.ring.empty() ? 0 : 2) + (cloud.t.empty() ? 0 : 4);
  const std::size_t header = out.size();
  out.resize(header + point_bytes * cloud.size());
  char* p = out.data() + header;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    std::memcpy(p, &cloud.xyz[3 * i], 12);
    p += 12;
    if (!cloud.intensity.empty()) {
      std::memcpy(p, &cloud.intensity[i], 4);
      p += 4;
    }
    if (!cloud.ring.empty()) {
      std::memcpy(p, &cloud.ring[i], 2);
      p += 2;
    }
    if (!cloud.t.empty()) {
      std::memcpy(p, &cloud.t[i], 4);
      p += 4;
    }
  }
  return out;
}

core::CameraIntrinsics to_intrinsics(const bag::CameraInfo& info, const std::string& camera_name,
                                     const bag::MessageContext& context) {
  core::CameraIntrinsics in;
  in.camera_name = camera_name;
  in.width = static_cast<int>(std::min<std::uint32_t>(info.width, std::numeric_limits<int>::max()));
  in.height =
      static_cast<int>(std::min<std::uint32_t>(info.height, std::numeric_limits<int>::max()));
  in.fx = info.k[0];
  in.fy = info.k[4];
  in.cx = info.k[2];
  in.cy = info.k[5];
  if (info.distortion_model == "plumb_bob" || info.distortion_model.empty()) {
    in.model = core::DistortionModel::kPlumbBob;
  } else if (info.distortion_model == "equidistant") {
    in.model = core::DistortionModel::kEquidistant;
  } else {
    throw core::Error(where(context), "CameraInfo distortion_model '" + info.distortion_model +
                                          "' is not supported (expected plumb_bob or equidistant)");
  }
  const std::size_t n = static_cast<std::size_t>(core::distortion_size(in.model));
  if (info.d.size() > n &&
      std::any_of(info.d.begin() + n, info.d.end(), [](double v) { return v != 0.0; })) {
    throw core::Error(where(context), "CameraInfo has " + std::to_string(info.d.size()) +
                                          " distortion coefficients, " + info.distortion_model +
                                          " takes " + std::to_string(n));
  }
  in.distortion.assign(n, 0.0);
  std::copy_n(info.d.begin(), std::min(n, info.d.size()), in.distortion.begin());
  if (!(in.fx > 0.0) || !(in.fy > 0.0)) {
    throw core::Error(where(context), "CameraInfo K has no focal lengths (fx " +
                                          std::to_string(in.fx) + ", fy " + std::to_string(in.fy) +
                                          "): the camera was not calibrated");
  }
  const std::string problem = in.validate();
  if (!problem.empty()) throw core::Error(where(context), "CameraInfo: " + problem);
  return in;
}

}  // namespace rgbdt::import
