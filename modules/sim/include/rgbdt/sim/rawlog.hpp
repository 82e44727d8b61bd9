#pragma once
/// \file
/// The raw tilting-LIDAR stream as an MRPT rawlog, in the layout of
/// rgbdt/core/tilt_rig.hpp: observations only, in time order,
///   CObservation2DRangeScan "HOKUYO"      one per scan, stamped at beam 0
///   CObservationRawDAQ      "TILT_ENCODER" one per encoder sample:
///                            CNTRIN_double[0] = count, AIN_double[0] = angle [rad]
/// Readable by MRPT's rawlog-edit and RawLogViewer. MRPT stays private to this module.
#include <string>
#include <vector>

#include "rgbdt/core/tilt_rig.hpp"
#include "rgbdt/sim/lidar_sim.hpp"

namespace rgbdt::sim {

/// Writes scans and encoder samples merged by time (gzip-compressed, as MRPT writes
/// rawlogs). Times are session seconds and must be > 0 (MRPT's timestamp 0 means
/// "invalid"). Throws rgbdt::core::Error naming the file on failure.
void write_rawlog(const std::string& path, const core::ScannerSpec& scanner, const std::vector<RawScan>& scans,
                  const std::vector<EncoderSample>& encoder);

/// What read_rawlog found.
struct RawlogContents {
  std::vector<RawScan> scans;
  std::vector<EncoderSample> encoder;
  int other_objects = 0;  ///< observations of other kinds or labels
};

/// Reads a rawlog of the layout above (for tests and tools). Throws rgbdt::core::Error
/// naming the file when it cannot be read.
RawlogContents read_rawlog(const std::string& path);

}  // namespace rgbdt::sim
