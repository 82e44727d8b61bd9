#pragma once
/// \file
/// The raw tilting-LIDAR stream as an MRPT rawlog (rgbdt/core/tilt_rig.hpp): an
/// observations-only rawlog of CObservation2DRangeScan ("HOKUYO", one per scan, stamped
/// at beam 0) and CObservationRawDAQ ("TILT_ENCODER", CNTRIN_double[0] = count,
/// AIN_double[0] = angle [rad]). MRPT's own tools read it (`rawlog-edit --info -i f`).
///
/// Reading also accepts MRPT's older action/sensory-frame rawlogs (observations are taken
/// out of each CSensoryFrame, actions skipped). A truncated file is not fatal: everything
/// before the cut is delivered and the reader reports where and why it stopped.
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationRawDAQ.h>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/tilt_lidar/assembler.hpp"

namespace mrpt::io {
class CStream;
}
namespace mrpt::serialization {
class CArchive;
}

namespace rgbdt::tilt_lidar {

/// Sensor labels of the two streams (tilt_rig.hpp defaults).
struct StreamLabels {
  std::string scan = "HOKUYO";
  std::string encoder = "TILT_ENCODER";
};

/// Scan -> MRPT observation. `T_lidar_scanner`, if given, becomes sensorPose (the scanner's
/// pose at beam 0 in the lidar frame); otherwise the mount at tilt 0 is used.
mrpt::obs::CObservation2DRangeScan::Ptr to_observation(const Scan& scan, const core::TiltRig& rig,
                                                       const std::string& label,
                                                       const Eigen::Isometry3d* T_lidar_scanner = nullptr);
/// MRPT observation -> Scan (beam order made counter-clockwise if the scan is right-to-left
/// = false). Ranges of invalid beams are kept, with valid = 0.
Scan from_observation(const mrpt::obs::CObservation2DRangeScan& obs);

/// Encoder sample -> MRPT observation (count and angle, as the contract says).
mrpt::obs::CObservationRawDAQ::Ptr to_observation(const EncoderSample& sample, double count,
                                                  const std::string& label);
/// MRPT observation -> encoder sample: the angle from CNTRIN_double[0] through the motor
/// spec when a count is present, else AIN_double[0]. Throws rgbdt::core::Error if neither.
EncoderSample from_observation(const mrpt::obs::CObservationRawDAQ& obs, const core::TiltMotorSpec& motor);

struct RawlogWriterOptions {
  StreamLabels labels;
  /// gzip level 1-9, 0 = plain. Plain (default) keeps every record readable up to the last
  /// byte written if the recorder dies; gzip loses its unflushed block.
  int gzip_level = 0;
  std::string validate() const;
};

/// Appends observations to an observations-only rawlog. Each write is flushed to the OS so
/// that a crash of the process loses nothing already written.
class RawlogWriter {
 public:
  /// Throws rgbdt::core::Error naming the file if it cannot be created.
  RawlogWriter(const std::string& path, const core::TiltRig& rig, const RawlogWriterOptions& options = {});
  ~RawlogWriter();
  RawlogWriter(const RawlogWriter&) = delete;
  RawlogWriter& operator=(const RawlogWriter&) = delete;

  void write(const Scan& scan, const Eigen::Isometry3d* T_lidar_scanner = nullptr);
  void write(const EncoderSample& sample, double count);
  void write(const mrpt::obs::CObservation& observation);
  void close();

  std::int64_t records() const { return records_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  core::TiltRig rig_;
  RawlogWriterOptions options_;
  std::unique_ptr<mrpt::io::CStream> stream_;  // gzip
  int fd_ = -1;                                // plain
  std::int64_t records_ = 0;
};

/// Reads observations one by one.
class RawlogReader {
 public:
  /// Throws rgbdt::core::Error naming the file if it is missing or cannot be opened.
  explicit RawlogReader(const std::string& path);
  ~RawlogReader();
  RawlogReader(const RawlogReader&) = delete;
  RawlogReader& operator=(const RawlogReader&) = delete;

  /// The next observation, or nullptr at the end of the file or at the first unreadable
  /// record (then error() says which byte and why, and truncated() is true).
  mrpt::obs::CObservation::Ptr next();

  bool truncated() const { return !error_.empty(); }
  const std::string& error() const { return error_; }
  std::int64_t records() const { return records_; }  ///< top-level records read
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::unique_ptr<mrpt::io::CStream> stream_;
  std::unique_ptr<mrpt::serialization::CArchive> archive_;
  std::deque<mrpt::obs::CObservation::Ptr> queued_;  // from a sensory frame
  std::string error_;
  std::int64_t records_ = 0;
  bool at_end_ = false;
};

/// What a rawlog holds (for `rgbdt_tilt_lidar info`).
struct RawlogSummary {
  struct Stream {
    std::string class_name;
    std::int64_t count = 0;
    double first_time_s = 0.0, last_time_s = 0.0;
  };
  std::map<std::string, Stream> streams;  ///< by sensor label
  std::int64_t observations = 0;
  bool truncated = false;
  std::string error;  ///< why reading stopped early (empty if complete)
};
RawlogSummary summarize_rawlog(const std::string& path);

struct ReplayResult {
  std::int64_t scans = 0, encoder_samples = 0, other = 0;
  std::int64_t tilts = 0;
  bool truncated = false;
  std::string error;  ///< why reading stopped early (empty if the file is complete)
};

/// Feeds a rawlog into the assembler (observations with other labels are counted and
/// skipped) and hands every finished tilt to `on_tilt`, including the flushed last one.
ReplayResult replay_rawlog(const std::string& path, Assembler& assembler,
                           const std::function<void(TiltCloud&&)>& on_tilt, const StreamLabels& labels = {});

}  // namespace rgbdt::tilt_lidar
