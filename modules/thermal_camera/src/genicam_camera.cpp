#include "rgbdt/thermal_camera/genicam_camera.hpp"

#include <arv.h>

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <deque>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <thread>

#include "rgbdt/core/error.hpp"
#include "rgbdt/core/log.hpp"

namespace rgbdt::thermal_camera {
namespace {

using Clock = std::chrono::steady_clock;

std::string take_message(GError* error) {
  if (error == nullptr) return "unknown error";
  std::string m = error->message != nullptr ? error->message : "unknown error";
  g_error_free(error);
  return m;
}

std::string str_or_empty(const char* s) { return s != nullptr ? s : ""; }

// GenICam Bayer names give the colour of the first two pixels of the first row; OpenCV
// names the pattern by the second row's second and third pixels, hence the swap.
int bayer_to_bgr_code(const std::string& pixel_format) {
  if (pixel_format.rfind("BayerRG", 0) == 0) return cv::COLOR_BayerBG2BGR;
  if (pixel_format.rfind("BayerBG", 0) == 0) return cv::COLOR_BayerRG2BGR;
  if (pixel_format.rfind("BayerGR", 0) == 0) return cv::COLOR_BayerGB2BGR;
  if (pixel_format.rfind("BayerGB", 0) == 0) return cv::COLOR_BayerGR2BGR;
  return -1;
}

// OpenCV matrix type for the formats delivered as plain arrays of 8- or 16-bit samples;
// -1 when the format is packed or otherwise not handled.
int cv_type_for(ArvPixelFormat format) {
  switch (format) {
    case ARV_PIXEL_FORMAT_MONO_8:
    case ARV_PIXEL_FORMAT_BAYER_GR_8:
    case ARV_PIXEL_FORMAT_BAYER_RG_8:
    case ARV_PIXEL_FORMAT_BAYER_GB_8:
    case ARV_PIXEL_FORMAT_BAYER_BG_8:
      return CV_8UC1;
    case ARV_PIXEL_FORMAT_MONO_10:
    case ARV_PIXEL_FORMAT_MONO_12:
    case ARV_PIXEL_FORMAT_MONO_14:
    case ARV_PIXEL_FORMAT_MONO_16:
      return CV_16UC1;
    case ARV_PIXEL_FORMAT_RGB_8_PACKED:
      return CV_8UC3;
    default:
      return -1;
  }
}

// Local IPv4 interface whose subnet holds `device` (127.0.0.1 for loopback devices), so a
// GigE camera given by address is opened without broadcast discovery.
GInetAddress* interface_for(GInetAddress* device, std::string* why) {
  const auto* device_bytes = g_inet_address_to_bytes(device);
  uint32_t d = 0;
  std::memcpy(&d, device_bytes, 4);
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) {
    *why = "cannot list the network interfaces";
    return nullptr;
  }
  GInetAddress* found = nullptr;
  for (ifaddrs* it = list; it != nullptr && found == nullptr; it = it->ifa_next) {
    if (it->ifa_addr == nullptr || it->ifa_netmask == nullptr || it->ifa_addr->sa_family != AF_INET)
      continue;
    const uint32_t a = reinterpret_cast<sockaddr_in*>(it->ifa_addr)->sin_addr.s_addr;
    const uint32_t m = reinterpret_cast<sockaddr_in*>(it->ifa_netmask)->sin_addr.s_addr;
    if ((a & m) == (d & m)) {
      found =
          g_inet_address_new_from_bytes(reinterpret_cast<const guint8*>(&a), G_SOCKET_FAMILY_IPV4);
    }
  }
  freeifaddrs(list);
  if (found == nullptr) *why = "no local IPv4 interface on the subnet of this address";
  return found;
}

// Opens a GigE camera by IPv4 address (nullptr when `id` is not an address).
ArvCamera* open_by_address(const std::string& id, GError** error, std::string* why) {
  GInetAddress* device = g_inet_address_new_from_string(id.c_str());
  if (device == nullptr) return nullptr;
  if (g_inet_address_get_family(device) != G_SOCKET_FAMILY_IPV4) {
    g_object_unref(device);
    *why = "only IPv4 addresses are supported by GigE Vision";
    return nullptr;
  }
  GInetAddress* iface = interface_for(device, why);
  ArvCamera* camera = nullptr;
  if (iface != nullptr) {
    ArvDevice* arv_device = arv_gv_device_new(iface, device, error);
    if (arv_device != nullptr) {
      camera = arv_camera_new_with_device(arv_device, error);
      g_object_unref(arv_device);  // the camera holds its own reference
    }
    g_object_unref(iface);
  }
  g_object_unref(device);
  return camera;
}

bool is_ipv4_address(const std::string& id) {
  GInetAddress* a = g_inet_address_new_from_string(id.c_str());
  if (a == nullptr) return false;
  g_object_unref(a);
  return true;
}

// True when a local IPv4 interface's subnet holds the IPv4 `address`.
bool has_interface_for(const std::string& address) {
  GInetAddress* device = g_inet_address_new_from_string(address.c_str());
  if (device == nullptr) return false;
  std::string why;
  GInetAddress* iface = g_inet_address_get_family(device) == G_SOCKET_FAMILY_IPV4
                            ? interface_for(device, &why)
                            : nullptr;
  g_object_unref(device);
  if (iface == nullptr) return false;
  g_object_unref(iface);
  return true;
}

// The listed device that `id` names: by its id, its physical id (a GigE camera's MAC
// address) or "<vendor>-<serial>", as Aravis accepts them. nullptr when none does.
const DeviceInfo* find_listed(const std::vector<DeviceInfo>& devices, const std::string& id) {
  for (const auto& d : devices) {
    if (d.id == id) return &d;
  }
  for (const auto& d : devices) {
    if (!d.physical_id.empty() && d.physical_id == id) return &d;
    if (!d.serial.empty() && d.vendor + "-" + d.serial == id) return &d;
  }
  return nullptr;
}

std::string listed_ids(const std::vector<DeviceInfo>& devices) {
  if (devices.empty()) return "no camera is visible on the selected interfaces";
  std::string s = "the cameras visible on the selected interfaces are";
  for (size_t i = 0; i < devices.size(); ++i) s += (i == 0 ? " '" : ", '") + devices[i].id + "'";
  return s;
}

}  // namespace

void select_interfaces(const InterfaceSelection& selection) {
  const auto set = [](const char* name, bool on) {
    if (on) {
      arv_enable_interface(name);
    } else {
      arv_disable_interface(name);
    }
  };
  set("GigEVision", selection.gige);
  set("USB3Vision", selection.usb3);
  set("Fake", selection.fake);
}

std::vector<DeviceInfo> list_devices() {
  arv_update_device_list();
  std::vector<DeviceInfo> devices;
  const unsigned n = arv_get_n_devices();
  for (unsigned i = 0; i < n; ++i) {
    DeviceInfo d;
    d.id = str_or_empty(arv_get_device_id(i));
    d.protocol = str_or_empty(arv_get_device_protocol(i));
    d.vendor = str_or_empty(arv_get_device_vendor(i));
    d.model = str_or_empty(arv_get_device_model(i));
    d.serial = str_or_empty(arv_get_device_serial_nbr(i));
    d.address = str_or_empty(arv_get_device_address(i));
    d.physical_id = str_or_empty(arv_get_device_physical_id(i));
    devices.push_back(d);
  }
  return devices;
}

std::string GenicamOptions::validate() const {
  if (!pixel_format.empty() && pixel_format != "Mono8" && pixel_format != "Mono10" &&
      pixel_format != "Mono12" && pixel_format != "Mono14" && pixel_format != "Mono16" &&
      pixel_format != "RGB8" && bayer_to_bgr_code(pixel_format) < 0) {
    return "pixel_format = '" + pixel_format +
           "', expected Mono8, Mono10, Mono12, Mono14, Mono16, RGB8 or Bayer{RG,GR,GB,BG}8";
  }
  if (region && (region->x < 0 || region->y < 0 || region->width < 0 || region->height < 0)) {
    return "region has a negative value";
  }
  if (!(frame_rate_hz >= 0.0 && std::isfinite(frame_rate_hz)))
    return "frame_rate_hz = " + std::to_string(frame_rate_hz) + ", expected a finite value >= 0";
  if (!(exposure_us >= 0.0 && std::isfinite(exposure_us)))
    return "exposure_us = " + std::to_string(exposure_us) + ", expected a finite value >= 0";
  if (buffer_count < 2) return "buffer_count = " + std::to_string(buffer_count) + ", expected >= 2";
  if (timeout_ms < 1) return "timeout_ms = " + std::to_string(timeout_ms) + ", expected >= 1";
  if (timeouts_before_reconnect < 1) {
    return "timeouts_before_reconnect = " + std::to_string(timeouts_before_reconnect) +
           ", expected >= 1";
  }
  if (reconnect_interval_ms < 0) return "reconnect_interval_ms must be >= 0";
  if (packet_size_bytes < 0) return "packet_size_bytes must be >= 0";
  return {};
}

cv::Mat to_viewable(const Frame& frame) {
  const int code = bayer_to_bgr_code(frame.pixel_format);
  if (code < 0 || frame.image.type() != CV_8UC1) return frame.image;
  cv::Mat bgr;
  cv::cvtColor(frame.image, bgr, code);
  return bgr;
}

const char* to_string(GrabStatus status) {
  switch (status) {
    case GrabStatus::kFrame:
      return "frame";
    case GrabStatus::kIncomplete:
      return "incomplete";
    case GrabStatus::kTimeout:
      return "timeout";
    case GrabStatus::kDisconnected:
      return "disconnected";
    case GrabStatus::kReconnected:
      return "reconnected";
  }
  return "unknown";
}

struct GenicamCamera::Impl {
  std::string device_id;
  GenicamOptions options;
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  gulong control_lost_handler = 0;
  std::atomic<bool> control_lost{false};
  bool want_streaming = false;  // start() called and not stop()ped
  bool connected = false;
  int consecutive_timeouts = 0;
  Clock::time_point last_reconnect_attempt{};
  int reconnect_attempts = 0;
  std::string lost_reason;
  // Frame counter bookkeeping.
  bool have_last_id = false;
  uint64_t last_frame_id = 0;
  uint64_t underruns_seen = 0;
  StreamStatistics stats;
  std::deque<Clock::time_point> recent;  // reception times of the last second's frames
  // Releasing a GigE device that has gone away waits for Aravis's protocol timeouts
  // (several seconds); it is done here so that grab() keeps reporting promptly.
  std::thread releaser;
  std::atomic<bool> releasing{false};

  ~Impl() {
    close(true);
    if (releaser.joinable()) releaser.join();
  }

  static void on_control_lost(ArvDevice*, gpointer self) {
    // Called from Aravis's heartbeat thread: only flag it, grab() acts on it.
    static_cast<Impl*>(self)->control_lost.store(true);
  }

  [[noreturn]] void fail(const std::string& what, GError* error) const {
    throw core::Error("camera '" + device_id + "'", what + ": " + take_message(error));
  }

  void open() {
    GError* error = nullptr;
    std::string why;
    if (is_ipv4_address(device_id)) {
      camera = open_by_address(device_id, &error, &why);
      if (camera == nullptr) {
        throw core::Error("camera '" + device_id + "'",
                          "cannot open the GigE camera at this address: " +
                              (why.empty() ? take_message(error) : why));
      }
    } else {
      open_listed();
    }
    control_lost.store(false);
    control_lost_handler = g_signal_connect(arv_camera_get_device(camera), "control-lost",
                                            G_CALLBACK(&Impl::on_control_lost), this);
    connected = true;
    configure();
  }

  // Opens a camera named by id (not by address). A GigE camera is opened by the address
  // the device list gives for it, from the local interface on that address's subnet:
  // arv_camera_new(id) would take the interface whose discovery socket heard the camera
  // first, and a camera that answers on another interface's socket than the one its
  // stream reaches (arv-fake-gv-camera on 127.0.0.1 also answers the broadcast sent from
  // the Ethernet interface) then streams to a receiver that never sees a packet (Aravis's
  // packet socket listens on that other interface).
  void open_listed() {
    const std::vector<DeviceInfo> devices = list_devices();
    const DeviceInfo* listed = find_listed(devices, device_id);
    GError* error = nullptr;
    std::string why;
    if (listed != nullptr && listed->protocol == "GigEVision" && is_ipv4_address(listed->address) &&
        has_interface_for(listed->address)) {
      camera = open_by_address(listed->address, &error, &why);
      if (camera == nullptr) {
        throw core::Error("camera '" + device_id + "'",
                          "cannot open the GigE camera listed at " + listed->address + ": " +
                              (why.empty() ? take_message(error) : why));
      }
      return;
    }
    // USB3 Vision and fake cameras, a GigE camera on no local subnet, and the names Aravis
    // resolves itself but does not list (a GigE camera's user-defined name, a host name).
    camera = arv_camera_new(listed != nullptr ? listed->id.c_str() : device_id.c_str(), &error);
    if (camera == nullptr) {
      const std::string aravis = take_message(error);
      if (listed != nullptr)
        throw core::Error("camera '" + device_id + "'", "cannot open: " + aravis);
      throw core::Error(
          "camera '" + device_id + "'",
          "no camera has this id; " + listed_ids(devices) + " (Aravis: " + aravis + ")");
    }
  }

  void configure() {
    GError* error = nullptr;
    if (!options.pixel_format.empty()) {
      arv_camera_set_pixel_format_from_string(camera, options.pixel_format.c_str(), &error);
      if (error) fail("PixelFormat = " + options.pixel_format + " refused", error);
    }
    if (options.region) {
      gint sensor_w = 0, sensor_h = 0;
      arv_camera_get_sensor_size(camera, &sensor_w, &sensor_h, &error);
      if (error) fail("cannot read SensorWidth/SensorHeight", error);
      const Region& r = *options.region;
      const int w = r.width > 0 ? r.width : sensor_w - r.x;
      const int h = r.height > 0 ? r.height : sensor_h - r.y;
      arv_camera_set_region(camera, r.x, r.y, w, h, &error);
      if (error) {
        fail("region x=" + std::to_string(r.x) + " y=" + std::to_string(r.y) +
                 " width=" + std::to_string(w) + " height=" + std::to_string(h) + " refused",
             error);
      }
    }
    if (options.frame_rate_hz > 0.0) {
      arv_camera_set_frame_rate(camera, options.frame_rate_hz, &error);
      if (error)
        fail("AcquisitionFrameRate = " + std::to_string(options.frame_rate_hz) + " refused", error);
    }
    if (options.exposure_us > 0.0) {
      arv_camera_set_exposure_time(camera, options.exposure_us, &error);
      if (error)
        fail("ExposureTime = " + std::to_string(options.exposure_us) + " us refused", error);
    }
    if (arv_camera_is_gv_device(camera)) {
      if (options.packet_size_bytes > 0) {
        arv_camera_gv_set_packet_size(camera, options.packet_size_bytes, &error);
      } else {
        arv_camera_gv_auto_packet_size(camera, &error);
      }
      if (error) fail("GevSCPSPacketSize refused", error);
    }
  }

  void start_stream() {
    GError* error = nullptr;
    const ArvPixelFormat format = arv_camera_get_pixel_format(camera, &error);
    if (error) fail("cannot read PixelFormat", error);
    if (cv_type_for(format) < 0) {
      throw core::Error("camera '" + device_id + "'",
                        "pixel format '" +
                            str_or_empty(arv_camera_get_pixel_format_as_string(camera, nullptr)) +
                            "' is not supported (expected Mono8..Mono16, RGB8 or Bayer*8)");
    }
    arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
    if (error) fail("AcquisitionMode = Continuous refused", error);
    stream = arv_camera_create_stream(camera, nullptr, nullptr, &error);
    if (stream == nullptr) fail("cannot create the stream", error);
    const guint payload = arv_camera_get_payload(camera, &error);
    if (error) fail("cannot read PayloadSize", error);
    for (int i = 0; i < options.buffer_count; ++i) {
      arv_stream_push_buffer(stream, arv_buffer_new(payload, nullptr));
    }
    arv_camera_start_acquisition(camera, &error);
    if (error) fail("AcquisitionStart failed", error);
    have_last_id = false;
    underruns_seen = 0;
    consecutive_timeouts = 0;
  }

  // Releases the stream and the device. `device_alive` false skips AcquisitionStop, which
  // would only wait for the protocol timeouts of a device that is gone.
  void close(bool device_alive) {
    if (camera != nullptr && stream != nullptr && device_alive) {
      GError* error = nullptr;
      arv_camera_stop_acquisition(camera, &error);
      if (error)
        core::log_warning("camera '", device_id, "': AcquisitionStop: ", take_message(error));
    }
    if (stream != nullptr) {
      g_object_unref(stream);
      stream = nullptr;
    }
    if (camera != nullptr) {
      if (control_lost_handler != 0) {
        g_signal_handler_disconnect(arv_camera_get_device(camera), control_lost_handler);
        control_lost_handler = 0;
      }
      g_object_unref(camera);
      camera = nullptr;
    }
    connected = false;
  }

  // Hands the dead stream and device to a background thread (see `releaser`).
  void release_in_background() {
    if (releaser.joinable()) releaser.join();
    if (camera != nullptr && control_lost_handler != 0) {
      g_signal_handler_disconnect(arv_camera_get_device(camera), control_lost_handler);
      control_lost_handler = 0;
    }
    ArvStream* dead_stream = stream;
    ArvCamera* dead_camera = camera;
    stream = nullptr;
    camera = nullptr;
    connected = false;
    releasing.store(true);
    releaser = std::thread([this, dead_stream, dead_camera] {
      if (dead_stream != nullptr) g_object_unref(dead_stream);
      if (dead_camera != nullptr) g_object_unref(dead_camera);
      releasing.store(false);
    });
  }

  // True when the device answers a read of its first bootstrap register, which bypasses
  // the GenICam node cache.
  bool device_answers() {
    if (camera == nullptr || control_lost.load()) return false;
    GError* error = nullptr;
    guint32 value = 0;
    arv_device_read_register(arv_camera_get_device(camera), 0, &value, &error);
    if (error) {
      lost_reason = take_message(error);
      return false;
    }
    return true;
  }

  GrabResult declare_lost(const std::string& why) {
    ++stats.disconnects;
    lost_reason = why;
    core::log_warning("camera '", device_id, "' lost: ", why, "; reconnecting");
    release_in_background();
    reconnect_attempts = 0;
    last_reconnect_attempt = Clock::now();
    GrabResult r;
    r.status = GrabStatus::kDisconnected;
    r.message = "device '" + device_id + "' lost (" + why + "); reconnecting";
    return r;
  }

  GrabResult try_reconnect() {
    GrabResult r;
    if (releasing.load()) {
      // Reopening now could let the old handle's late "release control" reach the
      // device after the new one has taken control.
      std::this_thread::sleep_for(std::chrono::milliseconds(std::min(options.timeout_ms, 200)));
      r.status = GrabStatus::kDisconnected;
      r.message = "device '" + device_id + "' lost (" + lost_reason +
                  "); releasing the old connection before reconnecting";
      return r;
    }
    const auto interval = std::chrono::milliseconds(options.reconnect_interval_ms);
    const auto wait = last_reconnect_attempt + interval - Clock::now();
    if (wait > Clock::duration::zero()) std::this_thread::sleep_for(wait);
    last_reconnect_attempt = Clock::now();
    ++reconnect_attempts;
    try {
      open();
      if (want_streaming) start_stream();
    } catch (const std::exception& e) {
      close(false);
      r.status = GrabStatus::kDisconnected;
      r.message = "device '" + device_id + "' lost (" + lost_reason + "); reconnect attempt " +
                  std::to_string(reconnect_attempts) + " failed: " + e.what();
      return r;
    }
    ++stats.reconnects;
    core::log_info("camera '", device_id, "' reconnected after ", reconnect_attempts,
                   " attempt(s)");
    r.status = GrabStatus::kReconnected;
    r.message = "device '" + device_id + "' reconnected after " +
                std::to_string(reconnect_attempts) + " attempt(s)";
    return r;
  }

  void count_frame_id(uint64_t id) {
    if (have_last_id) {
      if (id > last_frame_id) {
        stats.frames_lost += id - last_frame_id - 1;
      } else if (last_frame_id <= 0xFFFF && id < last_frame_id && last_frame_id - id > 0x8000) {
        // GigE Vision 1.x block ids are 16 bits, wrap from 65535 to 1 (0 is reserved).
        stats.frames_lost += (0xFFFF - last_frame_id) + (id >= 1 ? id - 1 : 0);
      }
    }
    have_last_id = true;
    last_frame_id = id;
  }

  void count_underruns() {
    guint64 completed = 0, failures = 0, underruns = 0;
    arv_stream_get_statistics(stream, &completed, &failures, &underruns);
    if (underruns > underruns_seen) {
      stats.frames_lost += underruns - underruns_seen;
      underruns_seen = underruns;
    }
  }

  GrabResult grab() {
    if (!want_streaming) {
      throw std::logic_error("GenicamCamera::grab() called before start()");
    }
    if (!connected) return try_reconnect();
    if (control_lost.load()) return declare_lost("control channel lost (no heartbeat reply)");

    ArvBuffer* buffer =
        arv_stream_timeout_pop_buffer(stream, static_cast<guint64>(options.timeout_ms) * 1000);
    GrabResult r;
    if (buffer == nullptr) {
      ++stats.timeouts;
      ++consecutive_timeouts;
      if (consecutive_timeouts >= options.timeouts_before_reconnect && !device_answers()) {
        return declare_lost(control_lost.load()
                                ? "control channel lost"
                                : "no frame for " +
                                      std::to_string(consecutive_timeouts * options.timeout_ms) +
                                      " ms and no register reply: " + lost_reason);
      }
      r.status = GrabStatus::kTimeout;
      r.message = "no frame within " + std::to_string(options.timeout_ms) + " ms";
      return r;
    }
    consecutive_timeouts = 0;
    count_underruns();
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    if (status != ARV_BUFFER_STATUS_SUCCESS) {
      ++stats.frames_incomplete;
      count_frame_id(arv_buffer_get_frame_id(buffer));
      r.status = GrabStatus::kIncomplete;
      r.message = "frame " + std::to_string(arv_buffer_get_frame_id(buffer)) +
                  " incomplete (Aravis buffer status " + std::to_string(static_cast<int>(status)) +
                  ")";
      arv_stream_push_buffer(stream, buffer);
      return r;
    }
    const ArvPixelFormat format = arv_buffer_get_image_pixel_format(buffer);
    const int type = cv_type_for(format);
    const int width = arv_buffer_get_image_width(buffer);
    const int height = arv_buffer_get_image_height(buffer);
    size_t size = 0;
    const void* data = arv_buffer_get_image_data(buffer, &size);
    const size_t needed = static_cast<size_t>(width) * height * CV_ELEM_SIZE(type);
    if (type < 0 || data == nullptr || size < needed) {
      ++stats.frames_incomplete;
      r.status = GrabStatus::kIncomplete;
      r.message = "frame " + std::to_string(arv_buffer_get_frame_id(buffer)) + " has " +
                  std::to_string(size) + " bytes of image data, expected " +
                  std::to_string(needed) + " for " + std::to_string(width) + "x" +
                  std::to_string(height);
      arv_stream_push_buffer(stream, buffer);
      return r;
    }
    Frame& f = r.frame;
    const cv::Mat view(height, width, type, const_cast<void*>(data));
    if (type == CV_8UC3) {
      cv::cvtColor(view, f.image, cv::COLOR_RGB2BGR);
    } else {
      f.image = view.clone();
    }
    f.pixel_format = current_format_name(format);
    f.frame_id = arv_buffer_get_frame_id(buffer);
    f.device_timestamp_ns = arv_buffer_get_timestamp(buffer);
    f.host_timestamp_ns = arv_buffer_get_system_timestamp(buffer);
    arv_stream_push_buffer(stream, buffer);

    count_frame_id(f.frame_id);
    ++stats.frames_completed;
    const auto now = Clock::now();
    recent.push_back(now);
    while (!recent.empty() && now - recent.front() > std::chrono::seconds(1)) recent.pop_front();
    r.status = GrabStatus::kFrame;
    return r;
  }

  static std::string current_format_name(ArvPixelFormat format) {
    switch (format) {
      case ARV_PIXEL_FORMAT_MONO_8:
        return "Mono8";
      case ARV_PIXEL_FORMAT_MONO_10:
        return "Mono10";
      case ARV_PIXEL_FORMAT_MONO_12:
        return "Mono12";
      case ARV_PIXEL_FORMAT_MONO_14:
        return "Mono14";
      case ARV_PIXEL_FORMAT_MONO_16:
        return "Mono16";
      case ARV_PIXEL_FORMAT_BAYER_RG_8:
        return "BayerRG8";
      case ARV_PIXEL_FORMAT_BAYER_GR_8:
        return "BayerGR8";
      case ARV_PIXEL_FORMAT_BAYER_GB_8:
        return "BayerGB8";
      case ARV_PIXEL_FORMAT_BAYER_BG_8:
        return "BayerBG8";
      case ARV_PIXEL_FORMAT_RGB_8_PACKED:
        return "RGB8";
      default:
        return "0x" + std::to_string(static_cast<unsigned>(format));
    }
  }
};

GenicamCamera::GenicamCamera(const std::string& device_id, const GenicamOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (device_id.empty()) throw std::invalid_argument("GenicamCamera: empty device id");
  if (const auto why = options.validate(); !why.empty()) {
    throw std::invalid_argument("GenicamOptions: " + why);
  }
  impl_->device_id = device_id;
  impl_->options = options;
  impl_->open();
}

GenicamCamera::~GenicamCamera() = default;

const std::string& GenicamCamera::device_id() const { return impl_->device_id; }

DeviceInfo GenicamCamera::info() const {
  DeviceInfo d;
  d.id = impl_->device_id;
  if (impl_->camera == nullptr) return d;
  ArvCamera* c = impl_->camera;
  d.vendor = str_or_empty(arv_camera_get_vendor_name(c, nullptr));
  d.model = str_or_empty(arv_camera_get_model_name(c, nullptr));
  d.serial = str_or_empty(arv_camera_get_device_serial_number(c, nullptr));
  d.protocol = arv_camera_is_gv_device(c)   ? "GigEVision"
               : arv_camera_is_uv_device(c) ? "USB3Vision"
                                            : "Fake";
  return d;
}

std::string GenicamCamera::pixel_format() const {
  if (impl_->camera == nullptr) return {};
  GError* error = nullptr;
  const char* s = arv_camera_get_pixel_format_as_string(impl_->camera, &error);
  if (error) impl_->fail("cannot read PixelFormat", error);
  return str_or_empty(s);
}

Region GenicamCamera::region() const {
  Region r;
  if (impl_->camera == nullptr) return r;
  GError* error = nullptr;
  arv_camera_get_region(impl_->camera, &r.x, &r.y, &r.width, &r.height, &error);
  if (error) impl_->fail("cannot read the region", error);
  return r;
}

double GenicamCamera::frame_rate_hz() const {
  if (impl_->camera == nullptr) return 0.0;
  GError* error = nullptr;
  const double v = arv_camera_get_frame_rate(impl_->camera, &error);
  if (error) impl_->fail("cannot read AcquisitionFrameRate", error);
  return v;
}

double GenicamCamera::exposure_us() const {
  if (impl_->camera == nullptr) return 0.0;
  GError* error = nullptr;
  const double v = arv_camera_get_exposure_time(impl_->camera, &error);
  if (error) impl_->fail("cannot read ExposureTime", error);
  return v;
}

void GenicamCamera::start() {
  if (impl_->want_streaming) return;
  impl_->stats = {};
  impl_->recent.clear();
  impl_->want_streaming = true;
  if (impl_->connected) {
    try {
      impl_->start_stream();
    } catch (...) {
      impl_->want_streaming = false;
      throw;
    }
  }
}

void GenicamCamera::stop() {
  if (!impl_->want_streaming) return;
  impl_->want_streaming = false;
  if (impl_->stream != nullptr) {
    GError* error = nullptr;
    arv_camera_stop_acquisition(impl_->camera, &error);
    if (error)
      core::log_warning("camera '", impl_->device_id, "': AcquisitionStop: ", take_message(error));
    g_object_unref(impl_->stream);
    impl_->stream = nullptr;
  }
}

bool GenicamCamera::streaming() const { return impl_->want_streaming && impl_->connected; }

GrabResult GenicamCamera::grab() { return impl_->grab(); }

StreamStatistics GenicamCamera::statistics() const {
  StreamStatistics s = impl_->stats;
  const auto& recent = impl_->recent;
  if (recent.size() >= 2) {
    const double span_s = std::chrono::duration<double>(recent.back() - recent.front()).count();
    if (span_s > 0.0) s.frame_rate_hz = static_cast<double>(recent.size() - 1) / span_s;
  }
  return s;
}

}  // namespace rgbdt::thermal_camera
