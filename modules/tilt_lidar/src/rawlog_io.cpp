#include "rgbdt/tilt_lidar/rawlog_io.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>

#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CAction.h>
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
  // mrpt::Clock turns a non-finite time into an arbitrary tick count: refuse it here.
  if (!std::isfinite(scan.time_s)) throw std::invalid_argument("tilt_lidar: scan time is not finite");
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
    const float r = obs.getScanRange(i);
    // A range MRPT marks valid but that is NaN, infinite or negative is no return.
    const bool usable = std::isfinite(r) && r >= 0.0f;
    scan.ranges_m[k] = usable ? r : 0.0f;
    scan.valid[k] = usable && obs.getScanRangeValidity(i) ? 1 : 0;
    if (intensity) scan.intensity[k] = static_cast<float>(obs.getScanIntensity(i));
  }
  return scan;
}

mrpt::obs::CObservationRawDAQ::Ptr to_observation(const EncoderSample& sample, double count,
                                                  const std::string& label) {
  if (!std::isfinite(sample.time_s)) throw std::invalid_argument("tilt_lidar: encoder sample time is not finite");
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

namespace {

// A record's walk hit a class this reader has no layout for: MRPT reads it instead.
struct UnknownClass {
  std::string name;
};

// A record's walk found bytes that cannot be an MRPT object (corrupt) or ran out of data.
struct WalkError {
  std::string what;
  bool end_of_data = false;
};

constexpr std::uint8_t kEndFlag = 0x88;

// Walks one serialised MRPT object in the bytes of a record without allocating anything
// its fields claim: every count is checked against the bytes that exist (fetched through
// `fill`, which stops at the end of the stream and at the record cap) and against the
// physical limits. Mirrors the layouts of MRPT's serializeFrom() for the classes listed
// in rawlog_io.hpp.
class Walker {
 public:
  Walker(const std::function<bool(std::size_t)>& fill, const std::vector<std::uint8_t>& buf, const RawlogLimits& limits)
      : fill_(fill), buf_(buf), limits_(limits) {}

  std::size_t pos() const { return pos_; }

  /// The class of the record's top-level object as the stream spells it.
  const std::string& top_class() const { return top_class_; }

  // One object with its header; returns its class name (without namespace).
  std::string object() {
    const std::size_t at = pos_;
    const std::uint8_t b = get<std::uint8_t>();
    const bool old_format = (b & 0x80) == 0;
    if (old_format) {
      // Before MRPT 0.5.5 the name length was a little-endian uint32.
      if (get<std::uint8_t>() != 0 || get<std::uint8_t>() != 0 || get<std::uint8_t>() != 0) {
        throw WalkError{"byte " + std::to_string(at) + " of the record is not an MRPT object header"};
      }
    }
    const std::size_t len = b & 0x7F;
    if (len == 0 || len > 120) {
      throw WalkError{"object header at byte " + std::to_string(at) + " of the record names a class of " +
                      std::to_string(len) + " characters (expected 1..120)"};
    }
    need(len);
    std::string name(reinterpret_cast<const char*>(buf_.data() + pos_), len);
    pos_ += len;
    for (const char c : name) {
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == ':')) {
        throw WalkError{"object header at byte " + std::to_string(at) + " has a class name with byte " +
                        std::to_string(static_cast<unsigned char>(c)) + " (expected a C++ identifier)"};
      }
    }
    if (top_class_.empty()) top_class_ = name;
    if (const auto colon = name.rfind(':'); colon != std::string::npos) name = name.substr(colon + 1);
    int version = 0;
    if (old_format) {
      const auto v = get<std::int32_t>();
      if (v < 0 || v >= 255) throw WalkError{"class " + name + " has version " + std::to_string(v) + " (expected 0..254)"};
      version = v;
    } else if (name != "nullptr") {
      version = get<std::uint8_t>();
    }
    if (name != "nullptr") body(name, version);
    if (!old_format && get<std::uint8_t>() != kEndFlag) {
      throw WalkError{"object " + name + " at byte " + std::to_string(at) + " lacks its end flag 0x88 (corrupt record)"};
    }
    return name;
  }

 private:
  void need(std::uint64_t n) {
    if (n > limits_.max_record_bytes || pos_ + n > limits_.max_record_bytes) {
      throw WalkError{"record needs more than " + std::to_string(limits_.max_record_bytes) +
                      " bytes (a count or length field is corrupt)"};
    }
    if (!fill_(pos_ + static_cast<std::size_t>(n))) {
      throw WalkError{"record ends " + std::to_string(pos_ + n - buf_.size()) +
                          " bytes early (a count or length field claims more bytes than the file holds)",
                      true};
    }
  }
  template <typename T>
  T get() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, buf_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void skip(std::uint64_t n) {
    need(n);
    pos_ += static_cast<std::size_t>(n);
  }
  // A std::vector or std::string: uint32 count, then the elements.
  std::uint32_t array(std::size_t element_size, std::uint64_t max_count, const char* what) {
    const auto n = get<std::uint32_t>();
    if (n > max_count) {
      throw WalkError{std::string(what) + " count " + std::to_string(n) + " exceeds " + std::to_string(max_count)};
    }
    skip(static_cast<std::uint64_t>(n) * element_size);
    return n;
  }
  void string(const char* what) { array(1, limits_.max_string_bytes, what); }
  // MRPT reads a bool as one raw byte: anything but 0 or 1 would be an invalid bool.
  bool boolean(const char* what) {
    const auto b = get<std::uint8_t>();
    if (b > 1) throw WalkError{std::string(what) + " is byte " + std::to_string(b) + " (expected a bool, 0 or 1)"};
    return b != 0;
  }

  void matrix(std::size_t element_size) {
    const auto rows = get<std::uint32_t>();
    const auto cols = get<std::uint32_t>();
    const std::uint64_t n = static_cast<std::uint64_t>(rows) * cols;
    if (n > (1u << 20)) {
      throw WalkError{"matrix of " + std::to_string(rows) + "x" + std::to_string(cols) + " (expected at most 2^20 elements)"};
    }
    skip(n * element_size);
  }
  void expect_object(std::initializer_list<const char*> classes) {
    const std::size_t at = pos_;
    const std::string name = object();
    for (const char* c : classes)
      if (name == c) return;
    throw WalkError{"object at byte " + std::to_string(at) + " is a " + name + " where " + *classes.begin() +
                    " is expected"};
  }

  void body(const std::string& name, int version) {
    if (name == "CObservation2DRangeScan" && version <= 7) {
      skip(4);  // aperture
      boolean("rightToLeft");
      skip(4);  // maxRange
      expect_object({"CPose3D"});
      if (version < 6) expect_object({"CMatrix", "CMatrixF", "CMatrixD"});  // covSensorPose
      const auto n = get<std::uint32_t>();
      if (n > limits_.max_beams) {
        throw WalkError{"2D scan claims " + std::to_string(n) + " beams (expected at most " +
                        std::to_string(limits_.max_beams) + ")"};
      }
      skip(4ull * n);                  // ranges
      if (version >= 1) skip(n);       // validity
      if (version >= 2) skip(4);       // stdError
      if (version >= 3) skip(8);       // timestamp
      if (version >= 4) skip(4);       // beamAperture
      if (version >= 5) {
        string("sensor label");
        skip(8);  // deltaPitch (double)
      }
      if (version >= 7 && boolean("hasIntensity")) skip(4ull * n);  // intensity
    } else if (name == "CObservationRawDAQ" && version == 0) {
      string("sensor label");
      skip(8 + 8);  // timestamp, sample_rate
      const std::uint64_t any = limits_.max_record_bytes;
      array(1, any, "AIN_8bits");
      array(2, any, "AIN_16bits");
      array(4, any, "AIN_32bits");
      array(4, any, "AIN_float");
      array(8, any, "AIN_double");
      skip(2);  // AIN_channel_count (uint16)
      boolean("AIN_interleaved");
      array(1, any, "AOUT_8bits");
      array(2, any, "AOUT_16bits");
      array(4, any, "AOUT_float");
      array(8, any, "AOUT_double");
      array(1, any, "DIN");
      array(1, any, "DOUT");
      array(4, any, "CNTRIN_32bits");
      array(8, any, "CNTRIN_double");
    } else if (name == "CSensoryFrame" && version <= 2) {
      if (version < 2) skip(4);   // ID
      if (version == 0) skip(8);  // timestamp
      const auto n = get<std::uint32_t>();
      if (n > limits_.max_frame_observations) {
        throw WalkError{"sensory frame claims " + std::to_string(n) + " observations (expected at most " +
                        std::to_string(limits_.max_frame_observations) + ")"};
      }
      for (std::uint32_t i = 0; i < n; ++i) object();
    } else if (name == "CPose3D" && version <= 3) {
      if (version == 0) expect_object({"CMatrixF", "CMatrix"});
      else if (version == 1) expect_object({"CMatrixD"});
      else skip(version == 2 ? 7 * 8 : 12 * 8);
    } else if ((name == "CMatrixD") && version == 0) {
      matrix(8);
    } else if ((name == "CMatrixF" || name == "CMatrix") && version == 0) {
      matrix(4);
    } else {
      throw UnknownClass{name + " (version " + std::to_string(version) + ")"};
    }
  }

  const std::function<bool(std::size_t)>& fill_;
  const std::vector<std::uint8_t>& buf_;
  const RawlogLimits& limits_;
  std::size_t pos_ = 0;
  std::string top_class_;
};

}  // namespace

RawlogReader::RawlogReader(const std::string& path, const RawlogLimits& limits) : path_(path), limits_(limits) {
  // Classes such as CObservationRotatingScan live in mrpt-maps; register them so rawlogs
  // holding them are readable (and the library is linked even with --as-needed).
  mrpt::maps::registerAllClasses_mrpt_maps();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw core::Error(path, "rawlog file does not exist");
  if (std::filesystem::is_directory(path, ec)) throw core::Error(path, "is a directory, expected an MRPT rawlog file");
  auto in = std::make_unique<mrpt::io::CFileGZInputStream>();
  // CFileGZInputStream reads both gzip-compressed and plain rawlogs.
  bool opened = false;
  try {
    opened = in->open(path);
  } catch (const std::exception& e) {
    throw core::Error(path, "cannot open rawlog for reading: " + one_line(e.what()));
  }
  if (!opened) throw core::Error(path, "cannot open rawlog for reading");
  stream_ = std::move(in);
}

RawlogReader::~RawlogReader() = default;

bool RawlogReader::fill(std::size_t n) {
  if (n > limits_.max_record_bytes) {
    throw core::Error(path_, "record " + std::to_string(records_) + " at byte " + std::to_string(record_offset_) +
                                 " is larger than " + std::to_string(limits_.max_record_bytes) + " bytes");
  }
  // The buffer grows with the bytes that arrive (at most doubling per read), never with
  // what a field claims: a forged count costs the bytes the file really holds.
  constexpr std::size_t kChunk = 64 * 1024;
  while (buf_.size() < n && !stream_end_) {
    const std::size_t want = std::max(kChunk, buf_.size());
    const std::size_t old = buf_.size();
    buf_.resize(old + want);
    std::size_t got = 0;
    try {
      got = stream_->Read(buf_.data() + old, want);
    } catch (const std::exception& e) {
      buf_.resize(old);
      throw core::Error(path_, "reading (decompressing) byte " + std::to_string(record_offset_ + old) +
                                   " failed: " + one_line(e.what()));
    }
    buf_.resize(old + got);
    if (got == 0) stream_end_ = true;
  }
  return buf_.size() >= n;
}

mrpt::serialization::CSerializable::Ptr RawlogReader::read_record() {
  const std::function<bool(std::size_t)> fill = [this](std::size_t n) { return this->fill(n); };
  std::size_t extent = 0;
  bool walked = true;
  Walker w(fill, buf_, limits_);
  try {
    w.object();
    extent = w.pos();
  } catch (const UnknownClass&) {
    walked = false;
    const std::string& w_top = w.top_class();
    // A rawlog's records are observations, sensory frames, actions or action collections;
    // any other class is not a rawlog record and is not handed to MRPT.
    const auto* id = mrpt::rtti::findRegisteredClass(w_top, true);
    if (!id) throw core::Error(path_, "record holds class " + w_top + ", which is not a registered MRPT class");
    const bool record_class = id->derivedFrom(CLASS_ID(mrpt::obs::CObservation)) ||
                              id->derivedFrom(CLASS_ID(mrpt::obs::CAction)) ||
                              id == CLASS_ID(mrpt::obs::CSensoryFrame) || id == CLASS_ID(mrpt::obs::CActionCollection);
    if (!record_class) {
      throw core::Error(path_, "record holds a " + w_top +
                                   " (expected an observation, sensory frame, action or action collection)");
    }
  } catch (const WalkError& e) {
    throw core::Error(path_, e.what);
  }
  auto deserialise = [](const std::uint8_t* data, std::size_t size, std::size_t* used) {
    mrpt::io::CMemoryStream mem;
    mem.assignMemoryNotOwn(data, size);
    auto ar = mrpt::serialization::archiveFrom(mem);
    auto obj = ar.ReadObject();
    *used = static_cast<std::size_t>(mem.getPosition());
    return obj;
  };
  mrpt::serialization::CSerializable::Ptr obj;
  std::size_t used = 0;
  if (walked) {
    try {
      obj = deserialise(buf_.data(), extent, &used);
    } catch (const std::exception& e) {
      throw core::Error(path_, one_line(e.what()));
    }
    if (used != extent) {
      throw core::Error(path_, "MRPT read " + std::to_string(used) + " bytes of a record whose layout spans " +
                                   std::to_string(extent) + " (unexpected serialisation)");
    }
  } else {
    // A class without a walked layout: MRPT reads it from the bytes buffered so far,
    // growing the buffer (up to the record cap) while MRPT runs out of them.
    std::size_t window = std::max<std::size_t>(buf_.size(), 4096);
    for (;;) {
      fill(std::min(window, limits_.max_record_bytes));
      try {
        obj = deserialise(buf_.data(), buf_.size(), &used);
        break;
      } catch (const std::bad_alloc&) {
        throw core::Error(path_, "out of memory deserialising a record (a count field is corrupt)");
      } catch (const std::exception& e) {
        if (stream_end_ || buf_.size() >= limits_.max_record_bytes) throw core::Error(path_, one_line(e.what()));
        window = std::min(buf_.size() * 2, limits_.max_record_bytes);
      }
    }
  }
  buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(used));
  record_offset_ += used;
  return obj;
}

mrpt::obs::CObservation::Ptr RawlogReader::next() {
  while (queued_.empty()) {
    if (at_end_) return nullptr;
    mrpt::serialization::CSerializable::Ptr obj;
    try {
      if (!fill(1)) {  // a clean end: no byte of a further record
        at_end_ = true;
        return nullptr;
      }
      obj = read_record();
    } catch (const std::exception& e) {
      at_end_ = true;
      // Strip our own "path: " prefix; the message below names the file once.
      std::string what = e.what();
      if (what.rfind(path_ + ": ", 0) == 0) what = what.substr(path_.size() + 2);
      if (records_ == 0) {
        throw core::Error(path_, "is not an MRPT rawlog (plain or gzip-compressed serialised MRPT objects): "
                                 "its first record is unreadable: " + what);
      }
      error_ = path_ + ": record " + std::to_string(records_) + " at byte " + std::to_string(record_offset_) +
               " is unreadable (truncated or corrupt file; the " + std::to_string(records_) +
               " records before it were read): " + what;
      return nullptr;
    }
    ++records_;
    if (auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(obj)) {
      return obs;
    }
    if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(obj)) {
      for (const auto& o : *sf)
        if (o) queued_.push_back(o);
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
  if (s.observations == 0 && !s.truncated) {
    throw core::Error(path, "holds no observations (" + std::to_string(reader.records()) +
                                " records); expected an MRPT rawlog of sensor observations");
  }
  return s;
}

ReplayResult replay_rawlog(const std::string& path, Assembler& assembler,
                           const std::function<void(TiltCloud&&)>& on_tilt, const StreamLabels& labels,
                           const std::function<bool()>& stop) {
  ReplayResult r;
  RawlogReader reader(path);
  auto deliver = [&](std::vector<TiltCloud>&& tilts) {
    for (auto& t : tilts) {
      ++r.tilts;
      on_tilt(std::move(t));
    }
  };
  auto refuse = [&](const std::string& why) {
    r.truncated = true;
    r.error = path + ": record " + std::to_string(reader.record_index()) + " at byte " +
              std::to_string(reader.record_offset()) + ": " + why + " (the records before it were read)";
  };
  double last_encoder_s = -std::numeric_limits<double>::infinity();
  std::int64_t observations = 0;
  while (auto obs = reader.next()) {
    ++observations;
    if (obs->sensorLabel == labels.scan) {
      if (const auto* scan = dynamic_cast<const mrpt::obs::CObservation2DRangeScan*>(obs.get())) {
        const Scan sc = from_observation(*scan);  // NaN/negative ranges come out invalid
        if (!std::isfinite(sc.time_s)) {
          refuse("scan time is not finite");
          break;
        }
        for (std::size_t i = 0; i < scan->getScanSize(); ++i) {
          const float range = scan->getScanRange(i);
          if (scan->getScanRangeValidity(i) && !(std::isfinite(range) && range >= 0.0f)) ++r.beams_refused;
        }
        ++r.scans;
        deliver(assembler.add_scan(sc));
        if (stop && stop()) break;
        continue;
      }
    } else if (obs->sensorLabel == labels.encoder) {
      if (const auto* daq = dynamic_cast<const mrpt::obs::CObservationRawDAQ*>(obs.get())) {
        EncoderSample e;
        try {
          e = from_observation(*daq, assembler.rig().motor);
        } catch (const std::exception& ex) {
          refuse(ex.what());
          break;
        }
        if (!std::isfinite(e.time_s) || !std::isfinite(e.angle_rad)) {
          std::ostringstream os;
          os << "encoder sample time " << e.time_s << " s, angle " << e.angle_rad << " rad: expected finite values";
          refuse(os.str());
          break;
        }
        if (e.time_s < last_encoder_s) {
          std::ostringstream os;
          os.precision(15);
          os << "encoder sample time " << e.time_s << " s goes back from the previous sample's " << last_encoder_s
             << " s (expected non-decreasing times)";
          refuse(os.str());
          break;
        }
        last_encoder_s = e.time_s;
        ++r.encoder_samples;
        deliver(assembler.add_encoder_sample(e));
        if (stop && stop()) break;
        continue;
      }
    }
    ++r.other;
    if (stop && stop()) break;
  }
  if (stop && stop()) {
    r.interrupted = true;
    return r;  // the unfinished tilt is not complete: not flushed
  }
  if (!r.truncated) {
    r.truncated = reader.truncated();
    r.error = reader.error();
  }
  if (observations == 0 && !r.truncated) {
    throw core::Error(path, "holds no observations (" + std::to_string(reader.records()) +
                                " records); expected an MRPT rawlog of HOKUYO scans and TILT_ENCODER samples");
  }
  deliver(assembler.flush());
  return r;
}

}  // namespace rgbdt::tilt_lidar
