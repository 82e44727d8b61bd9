// rgbdt::bag alone: a std_msgs/String decoded from its CDR bytes, and a missing bag refused by
// name.
#include <rgbdt/bag/messages.hpp>
#include <rgbdt/bag/reader.hpp>

#include <cstdint>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

int main() {
  using namespace rgbdt;
  // CDR little endian: encapsulation 00 01 00 00, then uint32 length 6 and "hello\0".
  const std::vector<std::uint8_t> cdr = {0, 1, 0, 0, 6, 0, 0, 0, 'h', 'e', 'l', 'l', 'o', 0};
  const std::string text = bag::decode_string(cdr.data(), cdr.size(), {"/chatter", 0, 0});
  std::string refusal;
  try {
    bag::open_bag("no-such-recording.mcap");
  } catch (const std::exception& e) {
    refusal = e.what();
  }
  std::cout << "consumer bag: decoded \"" << text << "\"; a missing bag gives: " << refusal << "\n";
  return text == "hello" && refusal.find("no-such-recording.mcap") != std::string::npos ? 0 : 1;
}
