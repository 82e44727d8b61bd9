// FTDI USB-serial bridge driven through libusb. Protocol facts used (FTDI application
// note AN232B-05 "Configuring FT232R, FT2232 and FT232B Baud Rates" and the FTDI vendor
// requests as documented by the Linux ftdi_sio driver headers):
//   - vendor OUT control requests (bmRequestType 0x40) on the interface's channel index:
//     0x00 RESET (value 0 reset, 1 purge RX, 2 purge TX), 0x02 SET_FLOW_CTRL (0 = none),
//     0x03 SET_BAUD_RATE (divisor split over value/index), 0x04 SET_DATA (0x0008 = 8N1),
//     0x09 SET_LATENCY_TIMER (ms);
//   - data on one bulk IN and one bulk OUT endpoint per channel; every IN packet of
//     wMaxPacketSize bytes starts with two modem/line status bytes that are not data.
#include <libusb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"
#include "rgbdt/thermal_camera/serial_transport.hpp"

namespace rgbdt::thermal_camera {
namespace {

constexpr uint8_t kVendorOut =
    LIBUSB_REQUEST_TYPE_VENDOR | LIBUSB_RECIPIENT_DEVICE | LIBUSB_ENDPOINT_OUT;
constexpr uint8_t kReset = 0x00;
constexpr uint8_t kSetFlowCtrl = 0x02;
constexpr uint8_t kSetBaudRate = 0x03;
constexpr uint8_t kSetData = 0x04;
constexpr uint8_t kSetLatencyTimer = 0x09;
constexpr unsigned kControlTimeoutMs = 1000;

std::string usb_id(const FtdiUsbOptions& o) {
  char b[32];
  std::snprintf(b, sizeof b, "usb %04x:%04x", o.vendor_id, o.product_id);
  return std::string(b) + (o.serial.empty() ? "" : " serial " + o.serial);
}

}  // namespace

std::string FtdiUsbOptions::validate() const {
  if (interface_number < 0 || interface_number > 3) {
    return "interface_number = " + std::to_string(interface_number) + ", expected 0..3";
  }
  if (baud < 300 || baud > 3000000)
    return "baud = " + std::to_string(baud) + ", expected 300..3000000";
  if (latency_timer_ms < 1 || latency_timer_ms > 255) {
    return "latency_timer_ms = " + std::to_string(latency_timer_ms) + ", expected 1..255";
  }
  return {};
}

FtdiUsbTransport::BaudDivisor FtdiUsbTransport::baud_divisor(int baud) {
  if (baud <= 0) throw std::invalid_argument("baud = " + std::to_string(baud) + ", expected > 0");
  constexpr double kBaseHz = 3000000.0;
  BaudDivisor d;
  // Divisors 0 and 1 are special: 3 MHz and 2 MHz.
  if (baud >= 3000000) {
    d.actual_baud = kBaseHz;
    return d;
  }
  if (baud >= 2000000) {
    d.value = 1;
    d.actual_baud = 2000000.0;
    return d;
  }
  // Divisor in eighths: integer part in bits 0-13, the eighth in bits 14-16 with FTDI's
  // code order (0, 1/8 -> 3, 1/4 -> 2, 3/8 -> 4, 1/2 -> 1, 5/8 -> 5, 3/4 -> 6, 7/8 -> 7).
  static constexpr uint32_t kFracCode[8] = {0, 3, 2, 4, 1, 5, 6, 7};
  auto eighths = static_cast<uint32_t>(std::lround(kBaseHz * 8.0 / baud));
  eighths = std::clamp<uint32_t>(eighths, 16, 0x3FFF * 8 + 7);
  const uint32_t encoded = (eighths >> 3) | (kFracCode[eighths & 7] << 14);
  d.value = static_cast<uint16_t>(encoded & 0xFFFF);
  d.index = static_cast<uint16_t>(encoded >> 16);
  d.actual_baud = kBaseHz * 8.0 / eighths;
  return d;
}

struct FtdiUsbTransport::Impl {
  FtdiUsbOptions options;
  std::string name;
  libusb_context* context = nullptr;
  libusb_device_handle* handle = nullptr;
  bool kernel_driver_detached = false;
  bool claimed = false;
  uint8_t endpoint_in = 0x81;
  uint8_t endpoint_out = 0x02;
  int max_packet = 64;
  bool multi_channel = false;
  std::vector<uint8_t> rx;  // data received but not yet returned

  ~Impl() {
    if (handle != nullptr) {
      if (claimed) libusb_release_interface(handle, options.interface_number);
      if (kernel_driver_detached) libusb_attach_kernel_driver(handle, options.interface_number);
      libusb_close(handle);
    }
    if (context != nullptr) libusb_exit(context);
  }

  [[noreturn]] void fail(const std::string& what, int rc) const {
    throw core::Error(name, what + ": " + libusb_error_name(rc));
  }

  uint16_t channel_index() const { return static_cast<uint16_t>(options.interface_number + 1); }

  void control(uint8_t request, uint16_t value, uint16_t index, const std::string& what) {
    const int rc = libusb_control_transfer(handle, kVendorOut, request, value, index, nullptr, 0,
                                           kControlTimeoutMs);
    if (rc < 0) fail(what, rc);
  }

  void open() {
    int rc = libusb_init(&context);
    if (rc != 0) fail("libusb_init", rc);
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(context, &list);
    if (n < 0) fail("cannot list USB devices", static_cast<int>(n));
    for (ssize_t i = 0; i < n && handle == nullptr; ++i) {
      libusb_device_descriptor desc{};
      if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
      if (desc.idVendor != options.vendor_id || desc.idProduct != options.product_id) continue;
      libusb_device_handle* h = nullptr;
      rc = libusb_open(list[i], &h);
      if (rc != 0) {
        core::log_warning(name, ": found but cannot open (", libusb_error_name(rc),
                          "); check the udev permissions");
        continue;
      }
      if (!options.serial.empty()) {
        unsigned char text[128] = {0};
        const int len = desc.iSerialNumber == 0 ? -1
                                                : libusb_get_string_descriptor_ascii(
                                                      h, desc.iSerialNumber, text, sizeof text);
        if (len < 0 || options.serial != reinterpret_cast<char*>(text)) {
          libusb_close(h);
          continue;
        }
      }
      handle = h;
      find_endpoints(list[i]);
    }
    libusb_free_device_list(list, 1);
    if (handle == nullptr) {
      throw core::Error(name, "no such USB device (is the Tau2's USB-serial bridge plugged in?)");
    }
    if (libusb_kernel_driver_active(handle, options.interface_number) == 1) {
      rc = libusb_detach_kernel_driver(handle, options.interface_number);
      if (rc != 0) fail("cannot detach the kernel driver (ftdi_sio)", rc);
      kernel_driver_detached = true;
    }
    rc = libusb_claim_interface(handle, options.interface_number);
    if (rc != 0) fail("cannot claim interface " + std::to_string(options.interface_number), rc);
    claimed = true;

    const auto divisor = baud_divisor(options.baud);
    if (std::abs(divisor.actual_baud - options.baud) > 0.03 * options.baud) {
      throw core::Error(name, "baud " + std::to_string(options.baud) +
                                  " cannot be made within 3 % (nearest " +
                                  std::to_string(divisor.actual_baud) + ")");
    }
    // Multi-channel chips take the channel in the low byte of the index.
    const uint16_t baud_index = multi_channel
                                    ? static_cast<uint16_t>((divisor.index << 8) | channel_index())
                                    : divisor.index;
    control(kReset, 0, channel_index(), "RESET");
    control(kSetFlowCtrl, 0, channel_index(), "SET_FLOW_CTRL none");
    control(kSetBaudRate, divisor.value, baud_index,
            "SET_BAUD_RATE " + std::to_string(options.baud));
    control(kSetData, 0x0008, channel_index(), "SET_DATA 8N1");
    control(kSetLatencyTimer, static_cast<uint16_t>(options.latency_timer_ms), channel_index(),
            "SET_LATENCY_TIMER");
    control(kReset, 1, channel_index(), "purge RX");
  }

  void find_endpoints(libusb_device* device) {
    libusb_config_descriptor* config = nullptr;
    if (libusb_get_active_config_descriptor(device, &config) != 0) return;  // keep defaults
    multi_channel = config->bNumInterfaces > 1;
    if (options.interface_number < config->bNumInterfaces) {
      const libusb_interface& itf = config->interface[options.interface_number];
      if (itf.num_altsetting > 0) {
        const libusb_interface_descriptor& alt = itf.altsetting[0];
        for (int e = 0; e < alt.bNumEndpoints; ++e) {
          const libusb_endpoint_descriptor& ep = alt.endpoint[e];
          if ((ep.bmAttributes & 0x3) != LIBUSB_TRANSFER_TYPE_BULK) continue;
          if (ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) {
            endpoint_in = ep.bEndpointAddress;
            max_packet = std::max<int>(ep.wMaxPacketSize, 8);
          } else {
            endpoint_out = ep.bEndpointAddress;
          }
        }
      }
    }
    libusb_free_config_descriptor(config);
  }
};

FtdiUsbTransport::FtdiUsbTransport(const FtdiUsbOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (const auto why = options.validate(); !why.empty()) {
    throw std::invalid_argument("FtdiUsbOptions: " + why);
  }
  impl_->options = options;
  impl_->name = usb_id(options);
  impl_->open();
}

FtdiUsbTransport::~FtdiUsbTransport() = default;

std::string FtdiUsbTransport::name() const { return impl_->name; }

void FtdiUsbTransport::write(const uint8_t* data, size_t size) {
  size_t done = 0;
  while (done < size) {
    int sent = 0;
    const int rc =
        libusb_bulk_transfer(impl_->handle, impl_->endpoint_out, const_cast<uint8_t*>(data + done),
                             static_cast<int>(size - done), &sent, 1000);
    if (rc != 0 && rc != LIBUSB_ERROR_TIMEOUT) impl_->fail("bulk write", rc);
    if (sent == 0 && rc == LIBUSB_ERROR_TIMEOUT)
      throw core::Error(impl_->name, "bulk write timed out");
    done += static_cast<size_t>(sent);
  }
}

size_t FtdiUsbTransport::read(uint8_t* data, size_t size, int timeout_ms) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  std::vector<uint8_t> packet(static_cast<size_t>(impl_->max_packet) * 8);
  // The chip answers every latency period with at least its two status bytes, so loop
  // until data arrives or the deadline passes.
  while (impl_->rx.empty()) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return 0;
    int got = 0;
    const int rc =
        libusb_bulk_transfer(impl_->handle, impl_->endpoint_in, packet.data(),
                             static_cast<int>(packet.size()), &got, static_cast<unsigned>(left));
    if (rc != 0 && rc != LIBUSB_ERROR_TIMEOUT) impl_->fail("bulk read", rc);
    for (int offset = 0; offset < got; offset += impl_->max_packet) {
      const int chunk = std::min(impl_->max_packet, got - offset);
      if (chunk > 2)
        impl_->rx.insert(impl_->rx.end(), packet.begin() + offset + 2,
                         packet.begin() + offset + chunk);
    }
  }
  const size_t n = std::min(size, impl_->rx.size());
  std::copy_n(impl_->rx.begin(), n, data);
  impl_->rx.erase(impl_->rx.begin(), impl_->rx.begin() + static_cast<long>(n));
  return n;
}

void FtdiUsbTransport::flush_input() {
  impl_->rx.clear();
  impl_->control(kReset, 1, impl_->channel_index(), "purge RX");
}

}  // namespace rgbdt::thermal_camera
