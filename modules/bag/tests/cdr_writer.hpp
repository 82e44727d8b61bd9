#pragma once
// A test-only CDR encoder of the messages rgbdt::bag decodes, written independently of the
// decoder from the CDR rules: primitives aligned to their size counted after the 4-byte
// encapsulation header, strings as uint32 length (with NUL) + bytes + NUL, sequences as uint32
// count + elements.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "rgbdt/bag/messages.hpp"

namespace rgbdt::bag::test {

class CdrWriter {
 public:
  explicit CdrWriter(bool big_endian = false) : big_endian_(big_endian) {
    bytes_ = {0x00, static_cast<std::uint8_t>(big_endian ? 0x00 : 0x01), 0x00, 0x00};
  }

  template <typename T>
  void put(T value) {
    align(sizeof(T));
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    // The tests run on little-endian hosts; big endian reverses each primitive.
    if (big_endian_) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
    }
    bytes_.insert(bytes_.end(), raw, raw + sizeof(T));
  }
  void u8(std::uint8_t v) { put(v); }
  void u32(std::uint32_t v) { put(v); }
  void i32(std::int32_t v) { put(v); }
  void f64(double v) { put(v); }
  void string(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
  }
  void byte_sequence(const std::vector<std::uint8_t>& data) {
    u32(static_cast<std::uint32_t>(data.size()));
    bytes_.insert(bytes_.end(), data.begin(), data.end());
  }
  void header(const Header& h) {
    i32(h.stamp.sec);
    u32(h.stamp.nanosec);
    string(h.frame_id);
  }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  void align(std::size_t n) {
    while ((bytes_.size() - 4) % n != 0) bytes_.push_back(0);
  }
  bool big_endian_;
  std::vector<std::uint8_t> bytes_;
};

inline std::vector<std::uint8_t> encode(const PointCloud2& m, bool big_endian = false) {
  CdrWriter w(big_endian);
  w.header(m.header);
  w.u32(m.height);
  w.u32(m.width);
  w.u32(static_cast<std::uint32_t>(m.fields.size()));
  for (const PointField& f : m.fields) {
    w.string(f.name);
    w.u32(f.offset);
    w.u8(f.datatype);
    w.u32(f.count);
  }
  w.u8(m.is_bigendian);
  w.u32(m.point_step);
  w.u32(m.row_step);
  w.byte_sequence(m.data);
  w.u8(m.is_dense);
  return w.bytes();
}

inline std::vector<std::uint8_t> encode(const Image& m, bool big_endian = false) {
  CdrWriter w(big_endian);
  w.header(m.header);
  w.u32(m.height);
  w.u32(m.width);
  w.string(m.encoding);
  w.u8(m.is_bigendian);
  w.u32(m.step);
  w.byte_sequence(m.data);
  return w.bytes();
}

inline std::vector<std::uint8_t> encode(const CompressedImage& m, bool big_endian = false) {
  CdrWriter w(big_endian);
  w.header(m.header);
  w.string(m.format);
  w.byte_sequence(m.data);
  return w.bytes();
}

inline std::vector<std::uint8_t> encode(const CameraInfo& m, bool big_endian = false) {
  CdrWriter w(big_endian);
  w.header(m.header);
  w.u32(m.height);
  w.u32(m.width);
  w.string(m.distortion_model);
  w.u32(static_cast<std::uint32_t>(m.d.size()));
  for (double v : m.d) w.f64(v);
  for (double v : m.k) w.f64(v);
  for (double v : m.r) w.f64(v);
  for (double v : m.p) w.f64(v);
  w.u32(m.binning_x);
  w.u32(m.binning_y);
  w.u32(m.roi.x_offset);
  w.u32(m.roi.y_offset);
  w.u32(m.roi.height);
  w.u32(m.roi.width);
  w.u8(m.roi.do_rectify);
  return w.bytes();
}

inline std::vector<std::uint8_t> encode(const Imu& m, bool big_endian = false) {
  CdrWriter w(big_endian);
  w.header(m.header);
  for (double v : {m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w}) w.f64(v);
  for (double v : m.orientation_covariance) w.f64(v);
  for (double v : {m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z}) w.f64(v);
  for (double v : m.angular_velocity_covariance) w.f64(v);
  for (double v : {m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z}) {
    w.f64(v);
  }
  for (double v : m.linear_acceleration_covariance) w.f64(v);
  return w.bytes();
}

/// A cloud of `n` points with float32 x, y, z, intensity, uint16 ring and float32 time (the
/// Velodyne layout, 22 bytes padded to point_step 32); point i is (i, -2i, 0.5i), intensity
/// 10i, ring i % 16, time 1e-4 i s.
inline PointCloud2 velodyne_cloud(std::uint32_t n, std::int32_t sec, std::uint32_t nanosec) {
  PointCloud2 cloud;
  cloud.header.stamp = {sec, nanosec};
  cloud.header.frame_id = "velodyne";
  cloud.height = 1;
  cloud.width = n;
  cloud.fields = {{"x", 0, PointField::kFloat32, 1},    {"y", 4, PointField::kFloat32, 1},
                  {"z", 8, PointField::kFloat32, 1},    {"intensity", 12, PointField::kFloat32, 1},
                  {"ring", 16, PointField::kUint16, 1}, {"time", 18, PointField::kFloat32, 1}};
  cloud.point_step = 32;
  cloud.row_step = 32 * n;
  cloud.data.assign(std::size_t{32} * n, 0);
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint8_t* p = cloud.data.data() + std::size_t{32} * i;
    const float values[4] = {float(i), -2.0f * float(i), 0.5f * float(i), 10.0f * float(i)};
    std::memcpy(p, values, sizeof(values));
    const std::uint16_t ring = static_cast<std::uint16_t>(i % 16);
    std::memcpy(p + 16, &ring, 2);
    const float time = 1e-4f * float(i);
    std::memcpy(p + 18, &time, 4);
  }
  cloud.is_dense = true;
  return cloud;
}

}  // namespace rgbdt::bag::test
