#pragma once
// A bounded reader of the two wire formats of ROS messages: plain CDR (XCDR1), the encoding of
// ROS 2, and the ROS 1 serialization. It is written here rather than taken from eProsima's
// Fast-CDR (Debian's libfastcdr-dev) because that package is not part of the build machines'
// set, and the subset the sensor messages use is small: primitives (aligned to their size in
// CDR, packed in ROS 1), strings and sequences with a uint32 length prefix. Every length is
// checked against the bytes left before anything is allocated.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/bag/messages.hpp"

namespace rgbdt::bag::detail {

/// "topic /points, message 12 at 1700000000.100000000 s": where a message came from, for errors.
std::string describe(const MessageContext& context);

class MessageReader {
 public:
  /// Reads the 4-byte encapsulation header of a CDR message (a ROS 1 message has none);
  /// `type` names the message type in ROS 2 form ("sensor_msgs/msg/Image") for errors.
  MessageReader(const std::uint8_t* data, std::size_t size, const MessageContext& context,
                const char* type);

  std::uint8_t u8(const std::string& field);
  bool boolean(const std::string& field);
  std::int32_t i32(const std::string& field);
  std::uint32_t u32(const std::string& field);
  double f64(const std::string& field);

  /// A string: CDR has a uint32 length including the terminating NUL, the characters, the
  /// NUL; ROS 1 a uint32 length and the characters.
  std::string string(const std::string& field);
  /// sequence<uint8>: uint32 count, then the bytes.
  std::vector<std::uint8_t> bytes(const std::string& field);
  /// sequence<float64>.
  std::vector<double> doubles(const std::string& field);
  /// Fills a fixed-size array of float64 (no length prefix).
  void doubles(double* out, std::size_t n, const std::string& field);
  /// The element count of a sequence whose elements take at least `min_element_size` bytes
  /// each; throws when the bytes left cannot hold that many.
  std::uint32_t sequence_length(std::size_t min_element_size, const std::string& field);

  Time time(const std::string& field);
  Header header(const std::string& field);

  bool is_ros1() const { return ros1_; }

  /// Throws core::Error naming the message, the type and `field`.
  [[noreturn]] void fail(const std::string& field, const std::string& what) const;

 private:
  void align(std::size_t n, const std::string& field);
  void need(std::size_t n, const std::string& field);
  template <typename T>
  T primitive(const std::string& field);

  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::size_t origin_ = 0;  // where alignment counts from: after the CDR header
  bool swap_ = false;
  bool ros1_ = false;
  const MessageContext& context_;
  std::string type_;
};

}  // namespace rgbdt::bag::detail
