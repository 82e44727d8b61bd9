#pragma once
/// \file
/// GenICam cameras (GigE Vision, USB3 Vision) through Aravis: the rig's RGB camera and
/// GenICam thermal cores. Open by Aravis device id, configure pixel format, region, frame
/// rate and exposure, stream into a pool of buffers, and keep going when the device times
/// out or disappears (grab() reports the state and reconnects by itself).
///
/// Thread use: one GenicamCamera is driven from one thread (grab() and the setters);
/// Aravis runs its own receive thread internally.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rgbdt::thermal_camera {

/// One camera as Aravis enumerates it.
struct DeviceInfo {
  std::string id;        ///< what GenicamCamera takes, e.g. "Fake_1", "Aravis-Fake-GV01"
  std::string protocol;  ///< "GigEVision", "USB3Vision", "Fake"
  std::string vendor;
  std::string model;
  std::string serial;
  std::string address;      ///< IP address for GigE, empty otherwise
  std::string physical_id;  ///< MAC address for GigE, bus position for USB3; may be empty
};

/// Which Aravis transport interfaces list_devices() and GenicamCamera search. Process-wide
/// (Aravis keeps one registry). GigE discovery broadcasts on every IPv4 interface; turn
/// it off to keep a process off the network (a GigE camera given by its IP address is
/// still reachable, see GenicamCamera).
struct InterfaceSelection {
  bool gige = true;   ///< GigE Vision (broadcast discovery)
  bool usb3 = true;   ///< USB3 Vision
  bool fake = false;  ///< Aravis's in-process fake camera, id "Fake_1" (tests, demos)
};
void select_interfaces(const InterfaceSelection& selection);

/// Cameras Aravis can see now on the selected interfaces (GigE discovery takes ~1 s).
std::vector<DeviceInfo> list_devices();

/// Region of interest on the sensor [px]; width/height 0 mean "up to the sensor edge".
struct Region {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

struct GenicamOptions {
  /// GenICam PixelFormat name: "Mono8", "Mono16", "BayerRG8", "BayerGR8", "BayerGB8",
  /// "BayerBG8". Empty keeps the camera's current format.
  std::string pixel_format;
  std::optional<Region> region;  ///< unset keeps the camera's current region
  double frame_rate_hz = 0.0;    ///< AcquisitionFrameRate; 0 keeps the camera's
  double exposure_us = 0.0;      ///< ExposureTime; 0 keeps the camera's (no auto change)
  int buffer_count = 16;         ///< buffers in the pool; raise for bursty hosts
  int timeout_ms = 1000;         ///< grab() waits this long before reporting a timeout
  /// After this many consecutive timeouts (or a lost control channel) the device is
  /// declared disconnected and reopened. Keep >= 1.
  int timeouts_before_reconnect = 2;
  int reconnect_interval_ms = 500;  ///< minimum time between two reopen attempts
  /// GigE only: GVSP packet size [bytes]; 0 lets Aravis negotiate it.
  int packet_size_bytes = 0;
  std::string validate() const;  ///< empty when valid, else the reason
};

/// One image with its time stamps. The image owns its pixels (copied out of the pool).
struct Frame {
  cv::Mat image;                     ///< CV_8UC1 (Mono8, Bayer*) or CV_16UC1 (Mono16)
  std::string pixel_format;          ///< GenICam name, e.g. "Mono16"
  uint64_t frame_id = 0;             ///< device frame counter (16-bit and wrapping on GigE v1)
  uint64_t device_timestamp_ns = 0;  ///< camera clock [ns]; 0 if the device gives none
  uint64_t host_timestamp_ns = 0;    ///< host wall clock at reception [ns since epoch]
};

/// The image as 8-bit BGR for Bayer formats (demosaiced), otherwise unchanged.
cv::Mat to_viewable(const Frame& frame);

/// What grab() found.
enum class GrabStatus {
  kFrame,         ///< a complete frame is in GrabResult::frame
  kIncomplete,    ///< a frame arrived damaged (missing packets, size mismatch); dropped
  kTimeout,       ///< nothing within timeout_ms; the device still answers
  kDisconnected,  ///< the device stopped answering; reopening it (see message)
  kReconnected,   ///< the device came back and streams again (no frame in this result)
};
const char* to_string(GrabStatus status);

struct GrabResult {
  GrabStatus status = GrabStatus::kTimeout;
  Frame frame;          ///< valid when status == kFrame
  std::string message;  ///< what happened, for logs and status lines
};

/// Counters since start().
struct StreamStatistics {
  uint64_t frames_completed = 0;   ///< complete frames returned by grab()
  uint64_t frames_incomplete = 0;  ///< frames that arrived damaged
  uint64_t frames_lost = 0;        ///< gaps in the device frame counter + pool underruns
  uint64_t timeouts = 0;           ///< grab() calls that waited timeout_ms in vain
  uint64_t disconnects = 0;        ///< times the device was declared lost
  uint64_t reconnects = 0;         ///< times it was reopened successfully
  double frame_rate_hz = 0.0;      ///< over the last ~1 s of complete frames
};

class GenicamCamera {
 public:
  /// Opens the device and applies the options. `device_id` is an Aravis id as listed by
  /// list_devices() ("Fake_1", "<vendor>-<serial>", a MAC address) or the IPv4 address
  /// of a GigE camera: an address is opened directly from the local interface on its
  /// subnet, without broadcast discovery (and 127.0.0.1 keeps all traffic on loopback). An
  /// id is looked up in list_devices() (one discovery on the selected interfaces, ~1 s with
  /// GigE, also on each reconnect attempt) and a GigE camera found there is opened by its
  /// address the same way. Throws std::invalid_argument for invalid options and
  /// rgbdt::core::Error (naming the device and the feature) when the device cannot be opened
  /// or refuses a setting; for an id no camera has, the message lists the ids there are.
  explicit GenicamCamera(const std::string& device_id, const GenicamOptions& options = {});
  /// May wait for a lost device's background release (Aravis's protocol timeouts, a few s).
  ~GenicamCamera();
  GenicamCamera(const GenicamCamera&) = delete;
  GenicamCamera& operator=(const GenicamCamera&) = delete;

  const std::string& device_id() const;
  DeviceInfo info() const;
  /// Current settings read back from the device.
  std::string pixel_format() const;
  Region region() const;
  double frame_rate_hz() const;
  double exposure_us() const;

  /// Creates the stream and starts acquisition. Throws rgbdt::core::Error on failure.
  void start();
  /// Stops acquisition and releases the stream; safe to call when stopped.
  void stop();
  bool streaming() const;

  /// Waits for the next frame (at most timeout_ms, plus one reopen attempt when the
  /// device is lost). Never throws for device trouble: that is reported in the status.
  /// Throws std::logic_error when called before start().
  ///
  /// Losing a device: after timeouts_before_reconnect empty waits the device is probed
  /// with a register read; if that fails (GigE: after Aravis's GVCP retries, ~5 s) or the
  /// control channel's heartbeat was lost, kDisconnected is returned, the old handle is
  /// released in the background, and later calls try to reopen it every
  /// reconnect_interval_ms until kReconnected. frames_lost counts counter gaps within a
  /// connection; frames the device never sent while it was away are not counted.
  GrabResult grab();

  StreamStatistics statistics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rgbdt::thermal_camera
