#pragma once
// A bounded reader of plain CDR (XCDR1), the encoding of ROS 2 messages. It is written here
// rather than taken from eProsima's Fast-CDR (Debian's libfastcdr-dev) because that package is
// not part of the build machines' set, and the subset ROS 2 sensor messages use is small:
// primitives aligned to their size, strings and sequences with a uint32 length prefix.
// Every length is checked against the bytes left before anything is allocated.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "rgbdt/bag/messages.hpp"

namespace rgbdt::bag::detail {

/// "topic /points, message 12 at 1700000000.100000000 s": where a message came from, for errors.
std::string describe(const MessageContext& context);

class CdrReader {
 public:
  /// Reads the 4-byte encapsulation header; `type` names the message type in errors.
  CdrReader(const std::uint8_t* data, std::size_t size, const MessageContext& context,
            const char* type);

  std::uint8_t u8(const std::string& field);
  bool boolean(const std::string& field);
  std::int32_t i32(const std::string& field);
  std::uint32_t u32(const std::string& field);
  double f64(const std::string& field);

  /// A string: uint32 length including the terminating NUL, the characters, the NUL.
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
  bool swap_ = false;
  const MessageContext& context_;
  const char* type_;
};

}  // namespace rgbdt::bag::detail
