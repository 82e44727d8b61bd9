#include "cdr.hpp"

#include <cstring>
#include <limits>
#include <type_traits>

#include "rgbdt/core/error.hpp"

namespace rgbdt::bag::detail {
namespace {

// CDR aligns each primitive to its size, counted from the first byte after the
// encapsulation header.
constexpr std::size_t kHeaderBytes = 4;

// "sensor_msgs/msg/Image" is "sensor_msgs/Image" in ROS 1.
std::string type_name(const char* ros2_type, Serialization serialization) {
  std::string name(ros2_type);
  const std::size_t msg = name.find("/msg/");
  if (serialization == Serialization::kRos1 && msg != std::string::npos) name.erase(msg, 4);
  return name;
}

bool host_is_little_endian() {
  const std::uint16_t one = 1;
  std::uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

std::string hex_byte(std::uint8_t b) {
  const char* digits = "0123456789abcdef";
  return std::string("0x") + digits[b >> 4] + digits[b & 15];
}

std::string format_time(std::int64_t ns) {
  const bool negative = ns < 0;
  const std::uint64_t magnitude =
      negative ? std::uint64_t(-(ns + 1)) + 1 : static_cast<std::uint64_t>(ns);
  std::string fraction = std::to_string(magnitude % 1000000000);
  fraction.insert(0, 9 - fraction.size(), '0');
  return (negative ? "-" : "") + std::to_string(magnitude / 1000000000) + "." + fraction + " s";
}

}  // namespace

std::string describe(const MessageContext& context) {
  return "topic " + context.topic + ", message " + std::to_string(context.index) + " at " +
         format_time(context.log_time_ns);
}

MessageReader::MessageReader(const std::uint8_t* data, std::size_t size,
                             const MessageContext& context, const char* type)
    : data_(data),
      size_(size),
      ros1_(context.serialization == Serialization::kRos1),
      context_(context),
      type_(type_name(type, context.serialization)) {
  if (ros1_) {
    // ROS 1 messages are little endian, without header or alignment.
    swap_ = !host_is_little_endian();
    return;
  }
  if (size_ < kHeaderBytes) {
    fail("(encapsulation header)", "message has " + std::to_string(size_) +
                                       " bytes, expected at least the 4-byte CDR header");
  }
  if (data_[0] != 0 || data_[1] > 1) {
    fail("(encapsulation header)",
         "encapsulation kind {" + hex_byte(data_[0]) + "," + hex_byte(data_[1]) +
             "}, expected plain CDR: {0x00,0x01} (little endian) or {0x00,0x00} (big endian)");
  }
  const bool little = data_[1] == 1;
  swap_ = little != host_is_little_endian();
  pos_ = kHeaderBytes;
  origin_ = kHeaderBytes;
}

void MessageReader::fail(const std::string& field, const std::string& what) const {
  throw core::Error(describe(context_), type_ + " field " + field + ": " + what);
}

void MessageReader::need(std::size_t n, const std::string& field) {
  if (n > size_ - pos_) {
    fail(field, "needs " + std::to_string(n) + " bytes at offset " + std::to_string(pos_) +
                    " but the message ends after " + std::to_string(size_ - pos_) +
                    " more (truncated or not this type)");
  }
}

void MessageReader::align(std::size_t n, const std::string& field) {
  if (ros1_) return;
  const std::size_t pad = (n - (pos_ - origin_) % n) % n;
  need(pad, field);
  pos_ += pad;
}

template <typename T>
T MessageReader::primitive(const std::string& field) {
  static_assert(std::is_arithmetic_v<T>);
  align(sizeof(T), field);
  need(sizeof(T), field);
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, data_ + pos_, sizeof(T));
  if (swap_) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  }
  pos_ += sizeof(T);
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

std::uint8_t MessageReader::u8(const std::string& field) { return primitive<std::uint8_t>(field); }

bool MessageReader::boolean(const std::string& field) {
  const std::uint8_t value = primitive<std::uint8_t>(field);
  if (value > 1) fail(field, "bool is " + std::to_string(value) + ", expected 0 or 1");
  return value == 1;
}

std::int32_t MessageReader::i32(const std::string& field) { return primitive<std::int32_t>(field); }
std::uint32_t MessageReader::u32(const std::string& field) {
  return primitive<std::uint32_t>(field);
}
double MessageReader::f64(const std::string& field) { return primitive<double>(field); }

std::uint32_t MessageReader::sequence_length(std::size_t min_element_size,
                                             const std::string& field) {
  const std::uint32_t count = u32(field + " (length)");
  const std::size_t left = size_ - pos_;
  if (min_element_size > 0 && count > left / min_element_size) {
    fail(field, "sequence of " + std::to_string(count) + " elements of " +
                    std::to_string(min_element_size) + " bytes, but only " + std::to_string(left) +
                    " bytes are left");
  }
  return count;
}

std::string MessageReader::string(const std::string& field) {
  const std::uint32_t length = sequence_length(1, field);
  if (ros1_) {
    std::string value(reinterpret_cast<const char*>(data_ + pos_), length);
    pos_ += length;
    return value;
  }
  // Some writers (not Fast-DDS) store an empty string as length 0 with no NUL.
  if (length == 0) return {};
  const char* chars = reinterpret_cast<const char*>(data_ + pos_);
  if (chars[length - 1] != '\0') {
    fail(field, "string of " + std::to_string(length) +
                    " bytes does not end with NUL (the length counts the terminating NUL)");
  }
  std::string value(chars, length - 1);
  pos_ += length;
  return value;
}

std::vector<std::uint8_t> MessageReader::bytes(const std::string& field) {
  const std::uint32_t count = sequence_length(1, field);
  std::vector<std::uint8_t> value(data_ + pos_, data_ + pos_ + count);
  pos_ += count;
  return value;
}

std::vector<double> MessageReader::doubles(const std::string& field) {
  const std::uint32_t count = sequence_length(sizeof(double), field);
  std::vector<double> value(count);
  doubles(value.data(), count, field);
  return value;
}

void MessageReader::doubles(double* out, std::size_t n, const std::string& field) {
  for (std::size_t i = 0; i < n; ++i) out[i] = f64(field + "[" + std::to_string(i) + "]");
}

Time MessageReader::time(const std::string& field) {
  Time t;
  if (ros1_) {
    // ROS 1 time: uint32 secs, uint32 nsecs.
    const std::uint32_t sec = u32(field + ".secs");
    if (sec > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max())) {
      fail(field + ".secs", std::to_string(sec) + " s is after 2038, beyond a 32-bit signed time");
    }
    t.sec = static_cast<std::int32_t>(sec);
    t.nanosec = u32(field + ".nsecs");
    return t;
  }
  t.sec = i32(field + ".sec");
  t.nanosec = u32(field + ".nanosec");
  return t;
}

Header MessageReader::header(const std::string& field) {
  Header h;
  if (ros1_) h.seq = u32(field + ".seq");
  h.stamp = time(field + ".stamp");
  h.frame_id = string(field + ".frame_id");
  return h;
}

}  // namespace rgbdt::bag::detail
