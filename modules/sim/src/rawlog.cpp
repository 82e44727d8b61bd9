#include "rgbdt/sim/rawlog.hpp"

#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationRawDAQ.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <cmath>
#include <exception>

#include "rgbdt/core/error.hpp"

namespace rgbdt::sim {

namespace {
const char* const kScanLabel = "HOKUYO";
const char* const kEncoderLabel = "TILT_ENCODER";
}  // namespace

void write_rawlog(const std::string& path, const core::ScannerSpec& scanner, const std::vector<RawScan>& scans,
                  const std::vector<EncoderSample>& encoder) {
  try {
    mrpt::io::CFileGZOutputStream file;
    if (!file.open(path, 1)) throw core::Error(path, "cannot open rawlog for writing");
    auto archive = mrpt::serialization::archiveFrom(file);
    size_t i = 0, k = 0;
    while (i < scans.size() || k < encoder.size()) {
      const bool take_scan = k >= encoder.size() || (i < scans.size() && scans[i].time_s <= encoder[k].time_s);
      const double t = take_scan ? scans[i].time_s : encoder[k].time_s;
      if (!(t > 0.0)) throw core::Error(path, "time " + std::to_string(t) + " s must be positive in an MRPT rawlog");
      if (take_scan) {
        const RawScan& s = scans[i++];
        mrpt::obs::CObservation2DRangeScan obs;
        obs.sensorLabel = kScanLabel;
        obs.timestamp = mrpt::Clock::fromDouble(s.time_s);
        obs.aperture = static_cast<float>(scanner.aperture_rad);
        obs.rightToLeft = true;  // beam i at -aperture/2 + i * step, counter-clockwise
        obs.maxRange = static_cast<float>(scanner.range_max_m);
        obs.stdError = 0.01f;
        obs.resizeScan(s.range_m.size());
        for (size_t b = 0; b < s.range_m.size(); ++b) {
          obs.setScanRange(b, s.range_m[b]);
          obs.setScanRangeValidity(b, s.valid[b] != 0);
          obs.setScanIntensity(b, static_cast<int>(std::lround(s.intensity[b])));
        }
        obs.setScanHasIntensity(true);
        archive << obs;
      } else {
        const EncoderSample& e = encoder[k++];
        mrpt::obs::CObservationRawDAQ obs;
        obs.sensorLabel = kEncoderLabel;
        obs.timestamp = mrpt::Clock::fromDouble(e.time_s);
        obs.CNTRIN_double = {e.count};
        obs.AIN_double = {e.angle_rad};
        obs.AIN_channel_count = 1;
        archive << obs;
      }
    }
  } catch (const core::Error&) {
    throw;
  } catch (const std::exception& e) {
    throw core::Error(path, std::string("writing the rawlog failed: ") + e.what());
  }
}

RawlogContents read_rawlog(const std::string& path) {
  RawlogContents out;
  mrpt::io::CFileGZInputStream file;
  if (!file.open(path)) throw core::Error(path, "cannot open rawlog");
  auto archive = mrpt::serialization::archiveFrom(file);
  for (;;) {
    mrpt::serialization::CSerializable::Ptr object;
    try {
      object = archive.ReadObject();
    } catch (const mrpt::serialization::CExceptionEOF&) {
      break;  // the normal end of the file
    } catch (const std::exception& e) {
      throw core::Error(path, std::string("corrupt rawlog after ") +
                                  std::to_string(out.scans.size() + out.encoder.size() + out.other_objects) +
                                  " objects: " + e.what());
    }
    if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(object);
        scan && scan->sensorLabel == kScanLabel) {
      RawScan s;
      s.time_s = mrpt::Clock::toDouble(scan->timestamp);
      for (size_t b = 0; b < scan->getScanSize(); ++b) {
        s.range_m.push_back(scan->getScanRange(b));
        s.valid.push_back(scan->getScanRangeValidity(b) ? 1 : 0);
        s.intensity.push_back(scan->hasIntensity() ? static_cast<float>(scan->getScanIntensity(b)) : 0.0f);
      }
      out.scans.push_back(std::move(s));
    } else if (auto daq = std::dynamic_pointer_cast<mrpt::obs::CObservationRawDAQ>(object);
               daq && daq->sensorLabel == kEncoderLabel && !daq->CNTRIN_double.empty() && !daq->AIN_double.empty()) {
      EncoderSample e;
      e.time_s = mrpt::Clock::toDouble(daq->timestamp);
      e.count = daq->CNTRIN_double[0];
      e.angle_rad = daq->AIN_double[0];
      out.encoder.push_back(e);
    } else {
      ++out.other_objects;
    }
  }
  return out;
}

}  // namespace rgbdt::sim
