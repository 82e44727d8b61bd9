#pragma once
/// \file
/// Assembly of a tilting 2D LIDAR: time-stamped scans + time-stamped tilt-encoder samples
/// -> one 3D cloud per tilt (one sweep of the motor between two direction reversals).
///
/// Geometry, frames and beam timing are those of rgbdt/core/tilt_rig.hpp: beam i of a
/// scan stamped t is measured at t + ScannerSpec::beam_time_offset(i); its tilt angle is
/// interpolated linearly between the two encoder samples around that time (per beam, not
/// per scan: a UTM-30LX scan lasts 25 ms while the tilt moves several degrees), and the
/// point is TiltRig::T_lidar_scanner(phi) * [r cos(theta), r sin(theta), 0].
///
/// The assembler is a streaming state machine: feed scans and encoder samples as they
/// arrive (any interleaving, moderately out of order), collect the finished tilts that
/// add_scan()/add_encoder_sample() return, and call flush() at the end of the stream.
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "rgbdt/cloud/point_types.hpp"
#include "rgbdt/core/tilt_rig.hpp"

namespace rgbdt::tilt_lidar {

/// One 2D scan as the scanner delivered it.
struct Scan {
  double time_s = 0.0;              ///< time of beam 0 [s], scanner clock
  std::vector<float> ranges_m;      ///< one per beam (ScannerSpec::beams)
  std::vector<std::uint8_t> valid;  ///< per beam, 0 = no return; empty = all valid
  std::vector<float> intensity;     ///< per beam, device units; may be empty
};

/// One reading of the tilt motor's encoder.
struct EncoderSample {
  double time_s = 0.0;     ///< sample time [s], encoder clock (see AssemblerOptions)
  double angle_rad = 0.0;  ///< tilt angle phi (TiltMotorSpec::angle_from_count of the count)
};

/// The spherical coordinates of a point as the sensor measured it (paper, Algorithm 2
/// sorts scan lines by phi and points along a line by theta).
struct SphericalPoint {
  float r_m = 0.0f;        ///< measured range [m]
  float theta_rad = 0.0f;  ///< beam angle in the scanner plane [rad]
  float phi_rad = 0.0f;    ///< interpolated tilt angle [rad]
};

struct AssemblerOptions {
  /// Samples further apart than this are a gap: beams inside it are dropped, not
  /// interpolated. Raise it for slow encoders (default fits 200 Hz with ~8 lost samples).
  double max_encoder_gap_s = 0.05;
  /// Encoder clock -> scanner clock: t_scanner = t_encoder + encoder_time_offset_s.
  double encoder_time_offset_s = 0.0;
  /// How late (in stream time) a sample may arrive and still be sorted in. Also the delay
  /// before a scan is assembled. Raise it if the streams are buffered unevenly.
  double reorder_window_s = 0.05;
  /// A scan waiting longer than this for encoder samples (measured in scan time) is
  /// assembled with whatever samples exist; uncovered beams are dropped and counted.
  double max_scan_wait_s = 0.5;
  /// The tilt must move back this far from an extreme before a reversal is declared:
  /// above encoder noise and quantisation (default ~6 counts of a 4096-count encoder).
  double reversal_hysteresis_rad = 0.5 * M_PI / 180.0;
  /// Tilts with fewer scan lines are discarded (counted in AssemblerStats::tilts_discarded).
  int min_scans_per_tilt = 2;
  std::string validate() const;  ///< empty when valid, else the reason
};

/// What happened to one tilt's beams.
struct TiltStats {
  int scans = 0;                 ///< scan lines with at least one point in this tilt (rings)
  std::int64_t beams = 0;        ///< beams that fell into this tilt's time span
  std::int64_t points = 0;       ///< beams that became points
  std::int64_t invalid = 0;      ///< no return, or range outside the scanner's limits
  std::int64_t dropped_gap = 0;  ///< inside an encoder gap longer than max_encoder_gap_s
  std::int64_t dropped_no_encoder = 0;  ///< before the first / after the last encoder sample
};

/// One assembled tilt.
struct TiltCloud {
  cloud::Cloud::Ptr cloud;                 ///< LIDAR frame; ring = scan index in the tilt,
                                           ///< t = seconds from the first point
  std::vector<SphericalPoint> spherical;   ///< parallel to cloud->points
  double start_time_s = 0.0;               ///< time of the first point, scanner clock
  double end_time_s = 0.0;                 ///< time of the last point
  int direction = 0;                       ///< +1 phi increasing, -1 decreasing, 0 unknown
  bool partial = false;  ///< not bounded by two reversals (start or end of the stream)
  TiltStats stats;
};

/// Totals over the whole stream.
struct AssemblerStats {
  std::int64_t scans = 0;
  std::int64_t scans_duplicate = 0;   ///< same timestamp as an earlier scan (dropped)
  std::int64_t scans_late = 0;        ///< older than what was already assembled (dropped)
  std::int64_t scans_reordered = 0;   ///< arrived out of order but sorted in
  std::int64_t scans_bad_size = 0;    ///< beam count differs from the rig (dropped)
  std::int64_t encoder_samples = 0;
  std::int64_t encoder_duplicate = 0; ///< same timestamp as an earlier sample (dropped)
  std::int64_t encoder_late = 0;      ///< arrived after the reorder window (dropped)
  std::int64_t encoder_reordered = 0; ///< arrived out of order but sorted in
  std::int64_t beams = 0, points = 0, invalid = 0, dropped_gap = 0, dropped_no_encoder = 0;
  std::int64_t reversals = 0;
  std::int64_t tilts = 0;             ///< tilts returned
  std::int64_t tilts_discarded = 0;   ///< below min_scans_per_tilt
};

class Assembler {
 public:
  /// Throws std::invalid_argument if the rig or the options are invalid.
  explicit Assembler(const core::TiltRig& rig, const AssemblerOptions& options = {});

  /// Adds one scan; returns the tilts this completed (usually none). Throws
  /// std::invalid_argument for a non-finite timestamp.
  std::vector<TiltCloud> add_scan(const Scan& scan);
  /// Adds one encoder sample; returns the tilts this completed.
  std::vector<TiltCloud> add_encoder_sample(const EncoderSample& sample);
  /// Assembles everything still buffered and returns the remaining tilts (the last one
  /// partial). The assembler can be reused afterwards for a new stream.
  std::vector<TiltCloud> flush();

  const AssemblerStats& stats() const { return stats_; }
  const core::TiltRig& rig() const { return rig_; }
  const AssemblerOptions& options() const { return options_; }

 private:
  struct Building {  // the tilt being filled
    cloud::Cloud::VectorType points;
    std::vector<SphericalPoint> spherical;
    std::vector<std::pair<double, std::uint8_t>> nonpoint;  // (time, why) of beams without a point
    // ring and t are written into each point as it is made (no per-point side arrays: the
    // < 1 ms per tilt budget): t is relative to t0_s, ring counts the scans with points.
    double t0_s = 0.0;            // time of the first point [s], scanner clock
    double last_time_s = -1e300;  // time of the last point [s]
    int ring = -1;                // ring of the last point
    std::int64_t ring_seq = -1;   // scan sequence number of that ring
    int direction = 0;
    bool starts_at_reversal = false;
  };

  void advance(bool flushing, std::vector<TiltCloud>& out);
  void detect_reversals(double horizon_s, std::vector<TiltCloud>& out);
  void on_reversal(double t_reversal_s, int new_direction, std::vector<TiltCloud>& out);
  void assemble_scan(const Scan& scan, std::int64_t seq, std::vector<TiltCloud>& out);
  void finish_tilt(Building& b, bool ends_at_reversal, std::vector<TiltCloud>& out);
  void trim_encoder();

  core::TiltRig rig_;
  AssemblerOptions options_;
  AssemblerStats stats_;

  // Beam direction in the lidar frame at tilt 0 is R_axis_scanner * [cos, sin, 0]; cached.
  std::vector<float> dir_x_, dir_y_, dir_z_, theta_;

  std::deque<EncoderSample> encoder_;  // sorted, scanner clock
  std::size_t detector_next_ = 0;      // next encoder_ index for the reversal detector
  double encoder_latest_s_ = -1e300;
  double encoder_final_s_ = -1e300;    // samples at or before this are final

  std::deque<Scan> scans_;  // sorted by time, waiting
  std::int64_t next_scan_seq_ = 0;
  double last_assembled_scan_s_ = -1e300;
  double scan_latest_s_ = -1e300;

  // Reversal detector (hysteresis on the encoder angle; plateau midpoint = turn time).
  int det_direction_ = 0;
  double det_start_angle_ = 0.0;
  bool det_started_ = false;
  double det_ext_angle_ = 0.0, det_ext_first_s_ = 0.0, det_ext_last_s_ = 0.0;
  std::deque<std::pair<double, int>> pending_reversals_;  // (time, new direction)

  Building building_;
};

}  // namespace rgbdt::tilt_lidar
