#include <gtest/gtest.h>

#include "rgbdt/thermal_camera/tau2_protocol.hpp"

using namespace rgbdt::thermal_camera::tau2;

namespace {

std::string decode_error(const std::vector<uint8_t>& bytes) {
  try {
    decode(bytes.data(), bytes.size());
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

TEST(Tau2Crc, MatchesTheCcittXmodemCheckValue) {
  // The standard check value of CRC-16/XMODEM (poly 0x1021, init 0) over "123456789".
  const std::string check = "123456789";
  EXPECT_EQ(crc16_ccitt(reinterpret_cast<const uint8_t*>(check.data()), check.size()), 0x31C3);
}

TEST(Tau2Packet, EncodesTheFfcModeQueryAsTheIddShowsIt) {
  // 6E 00 00 0B 00 00 2F 4A 00 00: FFC_MODE_SELECT get, as printed in the Tau2 IDD.
  const auto bytes = encode({0, static_cast<uint8_t>(Function::kFfcModeSelect), {}});
  const std::vector<uint8_t> expected = {0x6E, 0x00, 0x00, 0x0B, 0x00,
                                         0x00, 0x2F, 0x4A, 0x00, 0x00};
  EXPECT_EQ(bytes, expected);
}

TEST(Tau2Packet, RoundTripsEveryPayloadLength) {
  for (size_t n : std::vector<size_t>{0, 1, 2, 4, 8, 255, 256, 512}) {
    Packet p;
    p.status = 0x03;
    p.function = 0x8E;
    for (size_t i = 0; i < n; ++i) p.payload.push_back(static_cast<uint8_t>(i * 37 + 11));
    const auto bytes = encode(p);
    ASSERT_EQ(bytes.size(), kMinPacketBytes + n);
    const Packet q = decode(bytes.data(), bytes.size());
    EXPECT_EQ(q.status, p.status);
    EXPECT_EQ(q.function, p.function);
    EXPECT_EQ(q.payload, p.payload) << n;
  }
  EXPECT_THROW(encode({0, 0, std::vector<uint8_t>(kMaxPayloadBytes + 1)}), std::invalid_argument);
}

TEST(Tau2Packet, ParsesIncrementallyAndReportsTheBytesStillNeeded) {
  const auto bytes = encode({0, 0x20, words({0x0000})});
  for (size_t n = 0; n < bytes.size(); ++n) {
    const ParseResult r = parse(bytes.data(), n);
    ASSERT_EQ(r.kind, ParseResult::Kind::kNeedMore) << n;
    if (n >= kHeaderBytes) {
      EXPECT_EQ(r.needed, bytes.size());
    }
  }
  const ParseResult r = parse(bytes.data(), bytes.size());
  ASSERT_EQ(r.kind, ParseResult::Kind::kPacket);
  EXPECT_EQ(r.consumed, bytes.size());
}

TEST(Tau2Packet, RejectsABadHeaderCrc) {
  auto bytes = encode({0, 0x0C, {}});
  bytes[6] ^= 0x01;
  const std::string e = decode_error(bytes);
  EXPECT_NE(e.find("header CRC"), std::string::npos) << e;
  EXPECT_NE(e.find("0xAADA"), std::string::npos) << e;  // the computed value is named
}

TEST(Tau2Packet, RejectsABadPayloadCrc) {
  auto bytes = encode({0, 0x0A, words({2})});
  bytes[9] ^= 0x80;  // a payload bit, so CRC2 no longer matches
  const std::string e = decode_error(bytes);
  EXPECT_NE(e.find("payload CRC"), std::string::npos) << e;
}

TEST(Tau2Packet, RejectsAWrongProcessCode) {
  auto bytes = encode({0, 0x00, {}});
  bytes[0] = 0x6F;
  const std::string e = decode_error(bytes);
  EXPECT_NE(e.find("process code 0x6F, expected 0x6E"), std::string::npos) << e;
}

TEST(Tau2Packet, RejectsAWrongLength) {
  // Byte count larger than the data: truncated.
  auto longer = encode({0, 0x04, words({1, 2})});
  longer[5] = 6;
  const uint16_t crc1 = crc16_ccitt(longer.data(), 6);
  longer[6] = static_cast<uint8_t>(crc1 >> 8);
  longer[7] = static_cast<uint8_t>(crc1 & 0xFF);
  std::string e = decode_error(longer);
  EXPECT_NE(e.find("truncated packet: 14 bytes, expected 16"), std::string::npos) << e;
  // Byte count smaller than the data: CRC2 is read in the wrong place.
  auto shorter = encode({0, 0x04, words({1, 2})});
  shorter[5] = 2;
  const uint16_t crc1s = crc16_ccitt(shorter.data(), 6);
  shorter[6] = static_cast<uint8_t>(crc1s >> 8);
  shorter[7] = static_cast<uint8_t>(crc1s & 0xFF);
  e = decode_error(shorter);
  EXPECT_NE(e.find("payload CRC"), std::string::npos) << e;
  // Absurd byte count: rejected from the header alone, without waiting for 65535 bytes.
  auto huge = encode({0, 0x04, {}});
  huge[4] = 0xFF;
  huge[5] = 0xFF;
  const uint16_t crc1h = crc16_ccitt(huge.data(), 6);
  huge[6] = static_cast<uint8_t>(crc1h >> 8);
  huge[7] = static_cast<uint8_t>(crc1h & 0xFF);
  e = decode_error(huge);
  EXPECT_NE(e.find("byte count 65535 exceeds"), std::string::npos) << e;
}

TEST(Tau2Packet, RejectsTruncatedAndTrailingBytes) {
  const auto bytes = encode({0, 0x05, words({1, 2, 3, 4})});
  for (size_t n : std::vector<size_t>{0, 1, 5, 8, 12, bytes.size() - 1}) {
    const std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(n));
    const std::string e = decode_error(cut);
    EXPECT_NE(e.find("truncated"), std::string::npos) << n << ": " << e;
  }
  auto extra = bytes;
  extra.push_back(0x6E);
  const std::string e = decode_error(extra);
  EXPECT_NE(e.find("1 trailing bytes"), std::string::npos) << e;
}

TEST(Tau2Packet, NamesStatusesAndFunctions) {
  EXPECT_EQ(to_string(Status::kChecksumError), "CAM_CHECKSUM_ERROR");
  EXPECT_EQ(to_string(static_cast<Status>(0x42)), "status 0x42");
  EXPECT_EQ(function_name(0x0C), "DO_FFC");
  EXPECT_EQ(function_name(0x8E), "TLIN_COMMANDS");
  EXPECT_EQ(function_name(0x99), "function 0x99");
}
