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
///
/// Reading is bounded: each record is first walked in a buffer of the (decompressed) bytes
/// that really exist, and every count and length in it (beams, vector sizes, strings,
/// matrix sizes, observations of a sensory frame) is checked against those bytes and
/// against physical limits before MRPT deserialises it. A record never takes more than
/// RawlogLimits::max_record_bytes of memory in the buffer, whatever its fields claim, so
/// neither a forged count nor a gzip bomb allocates more than the file holds. Classes
/// other than the ones this reader walks (CObservation2DRangeScan, CObservationRawDAQ,
/// CSensoryFrame and the poses/matrices inside them) are handed to MRPT from that bounded
/// buffer; their own counts are MRPT's to check.
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

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

/// Limits of the bounded reader.
struct RawlogLimits {
  std::size_t max_record_bytes = 64u << 20;  ///< one record, decompressed
  std::uint32_t max_beams = 20000;           ///< of one 2D scan (a UTM-30LX has 1081)
  std::uint32_t max_string_bytes = 1u << 16; ///< sensor labels and other strings
  std::uint32_t max_frame_observations = 10000;  ///< in one CSensoryFrame
};

/// Reads observations one by one.
class RawlogReader {
 public:
  /// Throws rgbdt::core::Error naming the file if it is missing or cannot be opened.
  explicit RawlogReader(const std::string& path, const RawlogLimits& limits = {});
  ~RawlogReader();
  RawlogReader(const RawlogReader&) = delete;
  RawlogReader& operator=(const RawlogReader&) = delete;

  /// The next observation, or nullptr at the end of the file or at the first unreadable
  /// record (then error() says which byte and why, and truncated() is true). Throws
  /// rgbdt::core::Error naming the file if the very first record is unreadable: the file
  /// is not a rawlog (plain or gzip-compressed), e.g. gzip of other data.
  mrpt::obs::CObservation::Ptr next();
  /// The top-level record the last observation came from (0-based) and its byte offset in
  /// the decompressed stream, for messages that name a record.
  std::int64_t record_index() const { return records_ - 1; }
  std::uint64_t record_offset() const { return record_offset_; }

  bool truncated() const { return !error_.empty(); }
  const std::string& error() const { return error_; }
  std::int64_t records() const { return records_; }  ///< top-level records read
  const std::string& path() const { return path_; }

 private:
  // Makes at least `n` bytes from the start of the current record available in buf_;
  // false at the end of the stream. Throws core::Error past limits_.max_record_bytes.
  bool fill(std::size_t n);
  mrpt::serialization::CSerializable::Ptr read_record();

  std::string path_;
  RawlogLimits limits_;
  std::unique_ptr<mrpt::io::CStream> stream_;
  std::vector<std::uint8_t> buf_;  // bytes of the stream from record_offset_ on
  bool stream_end_ = false;
  std::deque<mrpt::obs::CObservation::Ptr> queued_;  // from a sensory frame
  std::string error_;
  std::int64_t records_ = 0;
  std::uint64_t record_offset_ = 0;
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
/// Throws rgbdt::core::Error naming the file if it holds no observations (not a rawlog).
RawlogSummary summarize_rawlog(const std::string& path);

struct ReplayResult {
  std::int64_t scans = 0, encoder_samples = 0, other = 0;
  std::int64_t tilts = 0;
  std::int64_t beams_refused = 0;  ///< ranges NaN, infinite or negative: marked invalid
  bool truncated = false;
  bool interrupted = false;  ///< `stop` returned true: the last, unfinished tilt is dropped
  std::string error;  ///< why reading stopped early (empty if the file is complete)
};

/// Feeds a rawlog into the assembler (observations with other labels are counted and
/// skipped) and hands every finished tilt to `on_tilt`, including the flushed last one.
/// An encoder sample whose time or angle is not finite, or whose time goes back from the
/// previous sample, stops reading like a damaged record (error names the record). `stop`,
/// if given, is polled after each record; when it returns true replay ends without
/// flushing the unfinished tilt. Throws rgbdt::core::Error naming the file if it holds no
/// observations at all (not a rawlog).
ReplayResult replay_rawlog(const std::string& path, Assembler& assembler,
                           const std::function<void(TiltCloud&&)>& on_tilt, const StreamLabels& labels = {},
                           const std::function<bool()>& stop = {});

}  // namespace rgbdt::tilt_lidar
