#include "rgbdt/tilt_lidar/rawlog_io.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CArchive.h>

#include "rgbdt/core/error.hpp"

namespace rgbdt::tilt_lidar {

namespace {

mrpt::poses::CPose3D to_pose(const Eigen::Isometry3d& T) {
  mrpt::math::CMatrixDouble44 M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = T.matrix()(r, c);
  return mrpt::poses::CPose3D(M);
}

// MRPT exceptions span several lines with a banner; keep the informative lines, joined.
std::string one_line(const std::string& text) {
  std::string out, line;
  std::istringstream is(text);
  while (std::getline(is, line)) {
    if (line.empty() || line.find("MRPT exception") != std::string::npos) continue;
    if (!out.empty()) out += " | ";
    out += line;
  }
  if (out.size() > 400) out = out.substr(0, 400) + "...";
  return out;
}

}  // namespace

mrpt::obs::CObservation2DRangeScan::Ptr to_observation(const Scan& scan, const core::TiltRig& rig,
                                                       const std::string& label,
                                                       const Eigen::Isometry3d* T_lidar_scanner) {
  auto obs = mrpt::obs::CObservation2DRangeScan::Create();
  obs->sensorLabel = label;
  obs->timestamp = mrpt::Clock::fromDouble(scan.time_s);
  obs->aperture = static_cast<float>(rig.scanner.aperture_rad);
  obs->rightToLeft = true;  // beam 0 at -aperture/2, counter-clockwise (tilt_rig.hpp)
  obs->maxRange = static_cast<float>(rig.scanner.range_max_m);
  obs->sensorPose = to_pose(T_lidar_scanner ? *T_lidar_scanner : rig.T_axis_scanner);
  const std::size_t n = scan.ranges_m.size();
  obs->resizeScan(n);
  obs->setScanHasIntensity(!scan.intensity.empty());
  for (std::size_t i = 0; i < n; ++i) {
    obs->setScanRange(i, scan.ranges_m[i]);
    obs->setScanRangeValidity(i, scan.valid.empty() || scan.valid[i] != 0);
    if (!scan.intensity.empty()) obs->setScanIntensity(i, static_cast<int>(std::lround(scan.intensity[i])));
  }
  return obs;
}

Scan from_observation(const mrpt::obs::CObservation2DRangeScan& obs) {
  Scan scan;
  scan.time_s = mrpt::Clock::toDouble(obs.timestamp);
  const std::size_t n = obs.getScanSize();
  scan.ranges_m.resize(n);
  scan.valid.resize(n);
  const bool intensity = obs.hasIntensity();
  if (intensity) scan.intensity.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = obs.rightToLeft ? k : n - 1 - k;
    scan.ranges_m[k] = obs.getScanRange(i);
    scan.valid[k] = obs.getScanRangeValidity(i) ? 1 : 0;
    if (intensity) scan.intensity[k] = static_cast<float>(obs.getScanIntensity(i));
  }
  return scan;
}

mrpt::obs::CObservationRawDAQ::Ptr to_observation(const EncoderSample& sample, double count,
                                                  const std::string& label) {
  auto obs = mrpt::obs::CObservationRawDAQ::Create();
  obs->sensorLabel = label;
  obs->timestamp = mrpt::Clock::fromDouble(sample.time_s);
  obs->CNTRIN_double = {count};
  obs->AIN_double = {sample.angle_rad};
  return obs;
}

EncoderSample from_observation(const mrpt::obs::CObservationRawDAQ& obs, const core::TiltMotorSpec& motor) {
  EncoderSample s;
  s.time_s = mrpt::Clock::toDouble(obs.timestamp);
  if (!obs.CNTRIN_double.empty()) s.angle_rad = motor.angle_from_count(obs.CNTRIN_double[0]);
  else if (!obs.AIN_double.empty()) s.angle_rad = obs.AIN_double[0];
  else throw core::Error(obs.sensorLabel, "encoder observation has neither CNTRIN_double[0] (count) nor AIN_double[0] (angle)");
  return s;
}

std::string RawlogWriterOptions::validate() const {
  if (gzip_level < 0 || gzip_level > 9) return "gzip_level " + std::to_string(gzip_level) + " must be in 0..9";
  if (labels.scan.empty() || labels.encoder.empty()) return "sensor labels must not be empty";
  return {};
}

RawlogWriter::RawlogWriter(const std::string& path, const core::TiltRig& rig, const RawlogWriterOptions& options)
    : path_(path), rig_(rig), options_(options) {
  if (const std::string why = options.validate(); !why.empty()) throw std::invalid_argument("RawlogWriter: " + why);
  if (options.gzip_level > 0) {
    auto gz = std::make_unique<mrpt::io::CFileGZOutputStream>();
    if (!gz->open(path, options.gzip_level)) throw core::Error(path, "cannot create rawlog for writing");
    stream_ = std::move(gz);
  } else {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) throw core::Error(path, std::string("cannot create rawlog for writing: ") + std::strerror(errno));
  }
}

RawlogWriter::~RawlogWriter() {
  try {
    close();
  } catch (...) {  // a destructor must not throw; close() explicitly to see errors
  }
}

void RawlogWriter::write(const Scan& scan, const Eigen::Isometry3d* T_lidar_scanner) {
  write(*to_observation(scan, rig_, options_.labels.scan, T_lidar_scanner));
}

void RawlogWriter::write(const EncoderSample& sample, double count) {
  write(*to_observation(sample, count, options_.labels.encoder));
}

void RawlogWriter::write(const mrpt::obs::CObservation& observation) {
  if (!stream_ && fd_ < 0) throw core::Error(path_, "rawlog writer is closed");
  try {
    if (stream_) {
      auto ar = mrpt::serialization::archiveFrom(*stream_);
      ar << observation;
    } else {
      // Serialise to memory, then one write(2): the record reaches the OS whole, so a
      // recorder that dies later leaves every earlier record readable.
      mrpt::io::CMemoryStream mem;
      auto ar = mrpt::serialization::archiveFrom(mem);
      ar << observation;
      const auto* bytes = static_cast<const char*>(mem.getRawBufferData());
      std::size_t left = mem.getTotalBytesCount();
      while (left > 0) {
        const ssize_t n = ::write(fd_, bytes, left);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) throw std::runtime_error(std::strerror(errno));
        bytes += n;
        left -= static_cast<std::size_t>(n);
      }
    }
  } catch (const std::exception& e) {
    throw core::Error(path_, std::string("writing record ") + std::to_string(records_) + " failed: " + e.what());
  }
  ++records_;
}

void RawlogWriter::close() {
  if (fd_ >= 0) {
    const int rc = ::close(fd_);
    fd_ = -1;
    if (rc != 0) throw core::Error(path_, std::string("closing rawlog failed: ") + std::strerror(errno));
  }
  if (stream_) {
    if (auto* g = dynamic_cast<mrpt::io::CFileGZOutputStream*>(stream_.get())) g->close();
    stream_.reset();
  }
}

RawlogReader::RawlogReader(const std::string& path) : path_(path) {
  // Classes such as CObservationRotatingScan live in mrpt-maps; register them so rawlogs
  // holding them are readable (and the library is linked even with --as-needed).
  mrpt::maps::registerAllClasses_mrpt_maps();
  if (!std::filesystem::exists(path)) throw core::Error(path, "rawlog file does not exist");
  auto in = std::make_unique<mrpt::io::CFileGZInputStream>();
  // CFileGZInputStream reads both gzip-compressed and plain rawlogs.
  if (!in->open(path)) throw core::Error(path, "cannot open rawlog for reading");
  stream_ = std::move(in);
  archive_ = std::make_unique<mrpt::serialization::CArchiveStreamBase<mrpt::io::CStream>>(*stream_);
}

RawlogReader::~RawlogReader() = default;

mrpt::obs::CObservation::Ptr RawlogReader::next() {
  while (queued_.empty()) {
    if (at_end_) return nullptr;
    const std::uint64_t before = stream_->getPosition();
    mrpt::serialization::CSerializable::Ptr obj;
    try {
      obj = archive_->ReadObject();
    } catch (const std::exception& e) {
      at_end_ = true;
      // A clean end of file is an EOF before the first byte of a record; anything else
      // (EOF inside a record, unknown class, corrupt bytes) stops reading with a reason.
      const bool clean_eof = dynamic_cast<const mrpt::serialization::CExceptionEOF*>(&e) != nullptr &&
                             stream_->getPosition() == before;
      if (!clean_eof) {
        const std::string what = one_line(e.what());
        error_ = path_ + ": record " + std::to_string(records_) + " at byte " + std::to_string(before) +
                 " is unreadable (truncated or corrupt file; the " + std::to_string(records_) +
                 " records before it were read): " + what;
      }
      return nullptr;
    }
    ++records_;
    if (auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj)) {
      return obs;
    }
    if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(obj)) {
      for (const auto& o : *sf) queued_.push_back(o);
    }
    // Actions (odometry) and other objects carry no sensor data for us: skipped.
  }
  auto obs = queued_.front();
  queued_.pop_front();
  return obs;
}

RawlogSummary summarize_rawlog(const std::string& path) {
  RawlogSummary s;
  RawlogReader reader(path);
  while (auto obs = reader.next()) {
    ++s.observations;
    auto& st = s.streams[obs->sensorLabel];
    const double t = mrpt::Clock::toDouble(obs->timestamp);
    if (st.count == 0) {
      st.class_name = obs->GetRuntimeClass()->className;
      st.first_time_s = t;
    }
    st.last_time_s = t;
    ++st.count;
  }
  s.truncated = reader.truncated();
  s.error = reader.error();
  return s;
}

ReplayResult replay_rawlog(const std::string& path, Assembler& assembler,
                           const std::function<void(TiltCloud&&)>& on_tilt, const StreamLabels& labels) {
  ReplayResult r;
  RawlogReader reader(path);
  auto deliver = [&](std::vector<TiltCloud>&& tilts) {
    for (auto& t : tilts) {
      ++r.tilts;
      on_tilt(std::move(t));
    }
  };
  while (auto obs = reader.next()) {
    if (obs->sensorLabel == labels.scan) {
      if (const auto* scan = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(obs.get())) {
        ++r.scans;
        deliver(assembler.add_scan(from_observation(*scan)));
        continue;
      }
    } else if (obs->sensorLabel == labels.encoder) {
      if (const auto* daq = dynamic_cast<const mrpt::obs::CObservationRawDAQ*>(obs.get())) {
        ++r.encoder_samples;
        deliver(assembler.add_encoder_sample(from_observation(*daq, assembler.rig().motor)));
        continue;
      }
    }
    ++r.other;
  }
  deliver(assembler.flush());
  r.truncated = reader.truncated();
  r.error = reader.error();
  return r;
}

}  // namespace rgbdt::tilt_lidar
