// The Tau2 client against the emulated camera on a pseudo-terminal: real termios I/O,
// real byte timing, no hardware.
#include <gtest/gtest.h>

#include "rgbdt/thermal_camera/radiometry.hpp"
#include "rgbdt/thermal_camera/tau2.hpp"

using namespace rgbdt::thermal_camera;
using tau2::Status;

namespace {

using PtyTau2 = Tau2PtyEmulator;

Tau2 connect(const PtyTau2& pty, int timeout_ms = 500) {
  Tau2Options o;
  o.reply_timeout_ms = timeout_ms;  // the pty answers within a few ms
  return Tau2(std::make_unique<TermiosTransport>(pty.path(), 57600), o);
}

template <typename E, typename Fn>
std::string error_of(Fn&& fn) {
  try {
    fn();
  } catch (const E& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Tau2, EveryCommandRoundTripsThroughTheEmulator) {
  PtyTau2 pty;
  Tau2 camera = connect(pty);
  camera.no_op();

  const Tau2SerialNumbers serial = camera.serial_numbers();
  EXPECT_EQ(serial.camera, 123456u);
  EXPECT_EQ(serial.sensor, 654321u);
  const Tau2Revision rev = camera.revision();
  EXPECT_EQ(rev.software_major, 2);
  EXPECT_EQ(rev.firmware_minor, 4);

  camera.do_ffc();
  camera.do_ffc();
  EXPECT_EQ(pty.with_emulator([](Tau2Emulator& e) { return e.state().ffc_count; }), 2);

  EXPECT_EQ(camera.ffc_mode(), Tau2FfcMode::kAutomatic);
  camera.set_ffc_mode(Tau2FfcMode::kManual);
  EXPECT_EQ(camera.ffc_mode(), Tau2FfcMode::kManual);

  EXPECT_EQ(camera.gain_mode(), Tau2GainMode::kAutomatic);
  camera.set_gain_mode(Tau2GainMode::kHighGain);
  EXPECT_EQ(camera.gain_mode(), Tau2GainMode::kHighGain);
  EXPECT_EQ(pty.with_emulator([](Tau2Emulator& e) { return e.state().gain_mode; }),
            Tau2GainMode::kHighGain);

  EXPECT_FALSE(camera.tlinear_enabled());
  camera.set_tlinear_enabled(true);
  EXPECT_TRUE(camera.tlinear_enabled());
  camera.set_tlinear_resolution(Tau2TLinearResolution::kLow);
  EXPECT_EQ(camera.tlinear_resolution(), Tau2TLinearResolution::kLow);
  // The resolution read back selects the linear radiometry of the stream.
  const Radiometry radiometry(LinearRadiometry{kelvin_per_count(camera.tlinear_resolution()), 0.0});
  EXPECT_NEAR(radiometry.kelvin(750), 300.0, 1e-9);

  // Exact scalings of the IDD: 0.1 degC and 0.01 degC per count.
  EXPECT_DOUBLE_EQ(camera.fpa_temperature_c(), 31.2);
  pty.with_emulator([](Tau2Emulator& e) { return e.state().fpa_temperature_c_x10 = -105; });
  EXPECT_DOUBLE_EQ(camera.fpa_temperature_c(), -10.5);
  EXPECT_DOUBLE_EQ(camera.shutter_temperature_c(), 29.87);

  camera.save_settings();
  EXPECT_EQ(pty.with_emulator([](Tau2Emulator& e) { return e.state().settings_saved; }), 1);
}

TEST(Tau2, CameraErrorStatusIsReportedByName) {
  PtyTau2 pty;
  Tau2 camera = connect(pty);
  // Gain mode 7 does not exist: the camera answers CAM_RANGE_ERROR.
  try {
    camera.transact(tau2::Function::kGainMode, tau2::words({7}));
    ADD_FAILURE() << "accepted gain mode 7";
  } catch (const Tau2Error& e) {
    EXPECT_EQ(e.status(), Status::kRangeError);
    EXPECT_NE(std::string(e.what()).find("GAIN_MODE failed: camera replied CAM_RANGE_ERROR"),
              std::string::npos)
        << e.what();
  }
  const std::string e =
      error_of<Tau2Error>([&] { camera.transact(static_cast<tau2::Function>(0x99)); });
  EXPECT_NE(e.find("CAM_UNDEFINED_FUNCTION_ERROR"), std::string::npos) << e;
  camera.no_op();  // the link is still in step afterwards
}

TEST(Tau2, CorruptRepliesAreRejectedWithAClearError) {
  PtyTau2 pty;
  Tau2 camera = connect(pty, 300);
  const auto expect_rejected = [&](Tau2Emulator::Fault fault, const std::string& part) {
    pty.with_emulator([&](Tau2Emulator& e) {
      e.inject_fault(fault);
      return 0;
    });
    const std::string e = error_of<rgbdt::core::Error>([&] { camera.serial_numbers(); });
    EXPECT_NE(e.find(part), std::string::npos) << e;
    EXPECT_NE(e.find(pty.path()), std::string::npos) << "error does not name the port: " << e;
    // The next command, on a clean line, works again.
    EXPECT_EQ(camera.serial_numbers().camera, 123456u);
  };
  expect_rejected(Tau2Emulator::Fault::kBadHeaderCrc, "corrupt reply to SERIAL_NUMBER: header CRC");
  expect_rejected(Tau2Emulator::Fault::kBadPayloadCrc,
                  "corrupt reply to SERIAL_NUMBER: payload CRC");
  expect_rejected(Tau2Emulator::Fault::kWrongByteCount,
                  "truncated reply to SERIAL_NUMBER: 18 bytes, expected 20");
  expect_rejected(Tau2Emulator::Fault::kTruncated, "truncated reply to SERIAL_NUMBER: 9 bytes");
  expect_rejected(Tau2Emulator::Fault::kNoReply, "no reply to SERIAL_NUMBER within 300 ms");
}

TEST(Tau2, EmulatorRejectsCorruptCommandsLikeTheCamera) {
  PtyTau2 pty;
  TermiosTransport port(pty.path());
  auto bad = tau2::encode({0, static_cast<uint8_t>(tau2::Function::kDoFfc), {}});
  bad.back() ^= 0xFF;
  port.write(bad.data(), bad.size());
  uint8_t buf[64];
  std::vector<uint8_t> reply;
  for (int i = 0; i < 50 && reply.size() < tau2::kMinPacketBytes; ++i) {
    const size_t n = port.read(buf, sizeof buf, 100);
    reply.insert(reply.end(), buf, buf + n);
  }
  const tau2::Packet p = tau2::decode(reply.data(), reply.size());
  EXPECT_EQ(static_cast<Status>(p.status), Status::kChecksumError);
  EXPECT_EQ(p.function, static_cast<uint8_t>(tau2::Function::kDoFfc));
  EXPECT_EQ(pty.with_emulator([](Tau2Emulator& e) { return e.state().ffc_count; }), 0);
}

TEST(Tau2, EmulatorAnswersPacketsSplitAndConcatenatedInMemory) {
  Tau2Emulator emulator;
  auto a = tau2::encode({0, static_cast<uint8_t>(tau2::Function::kNoOp), {}});
  const auto b =
      tau2::encode({0, static_cast<uint8_t>(tau2::Function::kGainMode), tau2::words({1})});
  a.insert(a.end(), b.begin(), b.end());
  std::vector<uint8_t> out;
  for (uint8_t byte : a) {  // one byte at a time, as a slow UART delivers them
    const auto r = emulator.feed(&byte, 1);
    out.insert(out.end(), r.begin(), r.end());
  }
  const auto first = tau2::parse(out.data(), out.size());
  ASSERT_EQ(first.kind, tau2::ParseResult::Kind::kPacket);
  EXPECT_EQ(first.packet.function, 0x00);
  const tau2::Packet second =
      tau2::decode(out.data() + first.consumed, out.size() - first.consumed);
  EXPECT_EQ(second.function, 0x0A);
  EXPECT_EQ(second.payload, tau2::words({1}));
  EXPECT_EQ(emulator.state().gain_mode, Tau2GainMode::kLowGain);
}

TEST(Tau2, TransportErrorsNameTheDevice) {
  const std::string e =
      error_of<rgbdt::core::Error>([] { TermiosTransport t("/dev/no-such-tau2"); });
  EXPECT_NE(e.find("/dev/no-such-tau2"), std::string::npos) << e;
  EXPECT_THROW(TermiosTransport("/dev/null", 12345), std::invalid_argument);
  EXPECT_THROW(Tau2(nullptr), std::invalid_argument);
}

TEST(FtdiUsb, BaudDivisorsFollowTheFtdiEncoding) {
  // 3 MHz / 57600 = 52.083 -> 52 + 1/8 (code 3): value = 52 | 3 << 14 = 0xC034.
  auto d = FtdiUsbTransport::baud_divisor(57600);
  EXPECT_EQ(d.value, 0xC034);
  EXPECT_EQ(d.index, 0);
  EXPECT_NEAR(d.actual_baud, 57553.96, 0.01);
  // 3 MHz / 921600 = 3.255 -> 3 + 1/4 (code 2): value = 3 | 2 << 14 = 0x8003.
  d = FtdiUsbTransport::baud_divisor(921600);
  EXPECT_EQ(d.value, 0x8003);
  EXPECT_NEAR(d.actual_baud, 923076.9, 0.1);
  // 3 MHz / 9600 = 312.5 -> 312 + 1/2 (code 1): value = 312 | 1 << 14 = 0x4138.
  d = FtdiUsbTransport::baud_divisor(9600);
  EXPECT_EQ(d.value, 0x4138);
  EXPECT_EQ(FtdiUsbTransport::baud_divisor(3000000).value, 0);
  EXPECT_EQ(FtdiUsbTransport::baud_divisor(2000000).value, 1);
  // 7/8 uses code 7, whose top bit lands in the index: 3 MHz / 3 + 7/8.
  d = FtdiUsbTransport::baud_divisor(774194);
  EXPECT_EQ(d.value, 3 | (3 << 14));
  EXPECT_EQ(d.index, 1);
}
