#include "rgbdt/tilt_lidar/assembler.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "rgbdt/core/log.hpp"

namespace rgbdt::tilt_lidar {

namespace {

constexpr double kSameTimeS = 1e-9;  // timestamps closer than this are duplicates
constexpr std::uint8_t kInvalid = 0, kGap = 1, kNoEncoder = 2;

// Room for `more` elements with geometric growth (an exact reserve per scan would copy the
// whole tilt on every scan). The first scan of a tilt reserves a typical 600 ms tilt.
template <typename V>
void grow(V& v, std::size_t more) {
  if (v.size() + more > v.capacity()) v.reserve(std::max({v.size() + more, 2 * v.capacity(), 26 * more}));
}
template <typename B>
void reserve_for(B& b, int n) {
  const auto more = static_cast<std::size_t>(n);
  grow(b.points, more);
  grow(b.spherical, more);
}

}  // namespace

std::string AssemblerOptions::validate() const {
  std::ostringstream os;
  if (!(max_encoder_gap_s > 0)) os << "max_encoder_gap_s " << max_encoder_gap_s << " must be positive";
  else if (!std::isfinite(encoder_time_offset_s)) os << "encoder_time_offset_s must be finite";
  else if (!(reorder_window_s >= 0) || !std::isfinite(reorder_window_s)) os << "reorder_window_s " << reorder_window_s << " must be >= 0";
  else if (!(max_scan_wait_s > 0)) os << "max_scan_wait_s " << max_scan_wait_s << " must be positive";
  else if (!(reversal_hysteresis_rad > 0)) os << "reversal_hysteresis_rad " << reversal_hysteresis_rad << " must be positive";
  else if (min_scans_per_tilt < 1) os << "min_scans_per_tilt " << min_scans_per_tilt << " must be at least 1";
  return os.str();
}

Assembler::Assembler(const core::TiltRig& rig, const AssemblerOptions& options)
    : rig_(rig), options_(options) {
  for (const std::string& why : {rig.scanner.validate(), rig.motor.validate(), options.validate()}) {
    if (!why.empty()) throw std::invalid_argument("tilt_lidar::Assembler: " + why);
  }
  const int n = rig_.scanner.beams;
  dir_x_.resize(n);
  dir_y_.resize(n);
  dir_z_.resize(n);
  theta_.resize(n);
  const Eigen::Matrix3d R_axis_scanner = rig_.T_axis_scanner.linear();
  for (int i = 0; i < n; ++i) {
    const double theta = rig_.scanner.beam_angle(i);
    const Eigen::Vector3d d = R_axis_scanner * Eigen::Vector3d(std::cos(theta), std::sin(theta), 0.0);
    dir_x_[i] = static_cast<float>(d.x());
    dir_y_[i] = static_cast<float>(d.y());
    dir_z_[i] = static_cast<float>(d.z());
    theta_[i] = static_cast<float>(theta);
  }
}

std::vector<TiltCloud> Assembler::add_scan(const Scan& scan) {
  if (!std::isfinite(scan.time_s)) throw std::invalid_argument("tilt_lidar::Assembler: scan time is not finite");
  std::vector<TiltCloud> out;
  ++stats_.scans;
  const std::size_t n = static_cast<std::size_t>(rig_.scanner.beams);
  if (scan.ranges_m.size() != n || (!scan.valid.empty() && scan.valid.size() != n) ||
      (!scan.intensity.empty() && scan.intensity.size() != n)) {
    if (stats_.scans_bad_size++ == 0) {
      core::log_warning("tilt_lidar: scan at ", scan.time_s, " s has ", scan.ranges_m.size(),
                        " ranges, the rig expects ", n, " beams; such scans are dropped");
    }
    return out;
  }
  if (scan.time_s <= last_assembled_scan_s_ + kSameTimeS) {
    if (std::abs(scan.time_s - last_assembled_scan_s_) <= kSameTimeS) ++stats_.scans_duplicate;
    else ++stats_.scans_late;
    return out;
  }
  auto it = std::lower_bound(scans_.begin(), scans_.end(), scan.time_s,
                             [](const Scan& s, double t) { return s.time_s < t; });
  if ((it != scans_.end() && it->time_s - scan.time_s <= kSameTimeS) ||
      (it != scans_.begin() && scan.time_s - std::prev(it)->time_s <= kSameTimeS)) {
    ++stats_.scans_duplicate;
    return out;
  }
  if (it != scans_.end()) ++stats_.scans_reordered;
  scans_.insert(it, scan);
  scan_latest_s_ = std::max(scan_latest_s_, scan.time_s);
  advance(false, out);
  return out;
}

std::vector<TiltCloud> Assembler::add_encoder_sample(const EncoderSample& sample) {
  if (!std::isfinite(sample.time_s) || !std::isfinite(sample.angle_rad)) {
    throw std::invalid_argument("tilt_lidar::Assembler: encoder sample time or angle is not finite");
  }
  std::vector<TiltCloud> out;
  ++stats_.encoder_samples;
  const EncoderSample s{sample.time_s + options_.encoder_time_offset_s, sample.angle_rad};
  if (s.time_s <= encoder_final_s_) {
    auto it = std::lower_bound(encoder_.begin(), encoder_.end(), s.time_s,
                               [](const EncoderSample& e, double t) { return e.time_s < t - kSameTimeS; });
    if (it != encoder_.end() && std::abs(it->time_s - s.time_s) <= kSameTimeS) ++stats_.encoder_duplicate;
    else ++stats_.encoder_late;
    return out;
  }
  if (encoder_.empty() || s.time_s > encoder_.back().time_s + kSameTimeS) {
    encoder_.push_back(s);
  } else {
    auto it = std::lower_bound(encoder_.begin(), encoder_.end(), s.time_s,
                               [](const EncoderSample& e, double t) { return e.time_s < t - kSameTimeS; });
    if (it != encoder_.end() && std::abs(it->time_s - s.time_s) <= kSameTimeS) {
      ++stats_.encoder_duplicate;
      return out;
    }
    ++stats_.encoder_reordered;
    encoder_.insert(it, s);  // after detector_next_: only final samples were detected
  }
  encoder_latest_s_ = std::max(encoder_latest_s_, s.time_s);
  advance(false, out);
  return out;
}

std::vector<TiltCloud> Assembler::flush() {
  std::vector<TiltCloud> out;
  advance(true, out);
  finish_tilt(building_, false, out);
  building_ = Building{};
  encoder_.clear();
  detector_next_ = 0;
  encoder_latest_s_ = encoder_final_s_ = -1e300;
  scans_.clear();
  last_assembled_scan_s_ = scan_latest_s_ = -1e300;
  det_direction_ = 0;
  det_started_ = false;
  pending_reversals_.clear();
  return out;
}

void Assembler::advance(bool flushing, std::vector<TiltCloud>& out) {
  const double horizon = flushing ? std::numeric_limits<double>::infinity()
                                  : encoder_latest_s_ - options_.reorder_window_s;
  encoder_final_s_ = std::max(encoder_final_s_, horizon);
  detect_reversals(encoder_final_s_, out);
  const double last_beam = rig_.scanner.beam_time_offset(rig_.scanner.beams - 1);
  while (!scans_.empty()) {
    const Scan& s = scans_.front();
    const bool covered = s.time_s + last_beam <= encoder_final_s_;
    const bool waited_enough = scan_latest_s_ - s.time_s > options_.max_scan_wait_s;
    if (!flushing && !covered && !waited_enough) break;
    const std::int64_t seq = next_scan_seq_++;
    assemble_scan(s, seq, out);
    last_assembled_scan_s_ = s.time_s;
    scans_.pop_front();
  }
  trim_encoder();
}

void Assembler::detect_reversals(double horizon_s, std::vector<TiltCloud>& out) {
  const double hyst = options_.reversal_hysteresis_rad;
  for (; detector_next_ < encoder_.size() && encoder_[detector_next_].time_s <= horizon_s; ++detector_next_) {
    const double t = encoder_[detector_next_].time_s;
    const double a = encoder_[detector_next_].angle_rad;
    if (!det_started_) {
      det_started_ = true;
      det_start_angle_ = a;
      continue;
    }
    if (det_direction_ == 0) {
      if (std::abs(a - det_start_angle_) > hyst) {
        det_direction_ = a > det_start_angle_ ? 1 : -1;
        det_ext_angle_ = a;
        det_ext_first_s_ = det_ext_last_s_ = t;
        if (building_.direction == 0) building_.direction = det_direction_;
      }
      continue;
    }
    const double ahead = (a - det_ext_angle_) * det_direction_;  // > 0: further along the sweep
    if (ahead > 1e-12) {
      det_ext_angle_ = a;
      det_ext_first_s_ = det_ext_last_s_ = t;
    } else if (ahead >= -1e-12) {
      det_ext_last_s_ = t;  // plateau at the extreme (quantised encoder)
    } else if (-ahead > hyst) {
      const double t_turn = 0.5 * (det_ext_first_s_ + det_ext_last_s_);
      det_direction_ = -det_direction_;
      det_ext_angle_ = a;
      det_ext_first_s_ = det_ext_last_s_ = t;
      on_reversal(t_turn, det_direction_, out);
    }
  }
}

void Assembler::on_reversal(double t_turn_s, int new_direction, std::vector<TiltCloud>& out) {
  ++stats_.reversals;
  Building& b = building_;
  const double last_np = b.nonpoint.empty() ? -1e300 : b.nonpoint.back().first;
  if (std::max(b.last_time_s, last_np) <= t_turn_s) {
    pending_reversals_.emplace_back(t_turn_s, new_direction);
    return;
  }
  // Beams after the turn were already assembled into this tilt: move them to the next one.
  Building next;
  next.direction = new_direction;
  next.starts_at_reversal = true;
  // Point times are float offsets from t0 (beams are 25 us apart; float resolution at 1 s
  // is 0.06 us), so the split on them is the split on the beam times.
  const float t_turn_rel = static_cast<float>(t_turn_s - b.t0_s);
  const std::size_t k = std::upper_bound(b.points.begin(), b.points.end(), t_turn_rel,
                                         [](float t, const cloud::PointXYZIRT& p) { return t < p.t; }) -
                        b.points.begin();
  if (k < b.points.size()) {
    const float t_first = b.points[k].t;
    const int ring_first = b.points[k].ring;
    next.points.assign(b.points.begin() + k, b.points.end());
    next.spherical.assign(b.spherical.begin() + k, b.spherical.end());
    for (auto& p : next.points) {
      p.t -= t_first;
      p.ring = static_cast<std::uint16_t>(p.ring - ring_first);
    }
    next.t0_s = b.t0_s + t_first;
    next.last_time_s = b.last_time_s;
    next.ring = b.ring - ring_first;
    next.ring_seq = b.ring_seq;
    b.points.resize(k);
    b.spherical.resize(k);
    b.last_time_s = k > 0 ? b.t0_s + b.points[k - 1].t : -1e300;
    b.ring = k > 0 ? b.points[k - 1].ring : -1;
  }
  const std::size_t m = std::upper_bound(b.nonpoint.begin(), b.nonpoint.end(), t_turn_s,
                                         [](double t, const auto& e) { return t < e.first; }) -
                        b.nonpoint.begin();
  next.nonpoint.assign(b.nonpoint.begin() + m, b.nonpoint.end());
  b.nonpoint.resize(m);
  finish_tilt(b, true, out);
  building_ = std::move(next);
}

void Assembler::assemble_scan(const Scan& scan, std::int64_t seq, std::vector<TiltCloud>& out) {
  const auto& spec = rig_.scanner;
  const int n = spec.beams;
  const double dt_beam = spec.scan_period_s / spec.steps_per_revolution;
  const Eigen::Vector3d t_as = rig_.T_axis_scanner.translation();
  const float tx = static_cast<float>(t_as.x()), ty = static_cast<float>(t_as.y()),
              tz = static_cast<float>(t_as.z());
  const float rmin = static_cast<float>(spec.range_min_m), rmax = static_cast<float>(spec.range_max_m);
  const double max_gap = options_.max_encoder_gap_s;
  const bool has_valid = !scan.valid.empty(), has_intensity = !scan.intensity.empty();

  // Encoder interval index j: encoder_[j].time_s <= tb < encoder_[j + 1].time_s.
  std::size_t j = 0;
  const std::size_t ne = encoder_.size();
  if (ne >= 2) {
    auto it = std::upper_bound(encoder_.begin(), encoder_.end(), scan.time_s,
                               [](double t, const EncoderSample& e) { return t < e.time_s; });
    j = it == encoder_.begin() ? 0 : static_cast<std::size_t>(it - encoder_.begin()) - 1;
  }
  double next_turn = pending_reversals_.empty() ? std::numeric_limits<double>::infinity()
                                                : pending_reversals_.front().first;
  Building* b = &building_;
  reserve_for(*b, n);
  std::size_t chain_j = static_cast<std::size_t>(-1);
  int chain_i = -2;
  double chain_phi = 0, chain_dphi = 0, chain_c = 1, chain_s = 0, chain_cd = 1, chain_sd = 0;
  for (int i = 0; i < n; ++i) {
    const double tb = scan.time_s + i * dt_beam;
    while (tb > next_turn) {  // a direction reversal inside this scan: Eq. split per beam
      const int dir = pending_reversals_.front().second;
      pending_reversals_.pop_front();
      finish_tilt(building_, true, out);
      building_ = Building{};
      building_.direction = dir;
      building_.starts_at_reversal = true;
      b = &building_;
      reserve_for(*b, n);
      next_turn = pending_reversals_.empty() ? std::numeric_limits<double>::infinity()
                                             : pending_reversals_.front().first;
    }
    const float r = scan.ranges_m[i];
    if ((has_valid && !scan.valid[i]) || !(r >= rmin && r <= rmax)) {
      b->nonpoint.emplace_back(tb, kInvalid);
      continue;
    }
    if (ne < 2 || tb < encoder_.front().time_s || tb > encoder_.back().time_s) {
      b->nonpoint.emplace_back(tb, kNoEncoder);
      continue;
    }
    while (j + 2 < ne && encoder_[j + 1].time_s <= tb) ++j;
    const EncoderSample& e0 = encoder_[j];
    const EncoderSample& e1 = encoder_[j + 1];
    const double span = e1.time_s - e0.time_s;
    if (span > max_gap) {
      b->nonpoint.emplace_back(tb, kGap);
      continue;
    }
    // phi is linear in time inside an encoder interval, so consecutive beams differ by a
    // constant rotation: step (cos, sin) by it instead of calling sin/cos per beam (the
    // < 1 ms per tilt budget). Restarted exactly at every interval and after any skipped beam.
    double phi, c, s;
    if (j == chain_j && i == chain_i + 1) {
      phi = chain_phi + chain_dphi;
      const double c1 = chain_c * chain_cd - chain_s * chain_sd;
      s = chain_s * chain_cd + chain_c * chain_sd;
      c = c1;
    } else {
      const double slope = (e1.angle_rad - e0.angle_rad) / span;
      phi = e0.angle_rad + slope * (tb - e0.time_s);
      c = std::cos(phi);
      s = std::sin(phi);
      chain_dphi = slope * dt_beam;
      chain_cd = std::cos(chain_dphi);
      chain_sd = std::sin(chain_dphi);
      chain_j = j;
    }
    chain_i = i;
    chain_phi = phi;
    chain_c = c;
    chain_s = s;
    // p_lidar = Ry(phi) * (r * d_i + t_axis_scanner)   (tilt_rig.hpp)
    const float px = r * dir_x_[i] + tx, py = r * dir_y_[i] + ty, pz = r * dir_z_[i] + tz;
    const float cf = static_cast<float>(c), sf = static_cast<float>(s);
    cloud::PointXYZIRT p;
    p.x = cf * px + sf * pz;
    p.y = py;
    p.z = -sf * px + cf * pz;
    p.intensity = has_intensity ? scan.intensity[i] : 0.0f;
    if (b->points.empty()) b->t0_s = tb;
    if (seq != b->ring_seq) {
      ++b->ring;
      b->ring_seq = seq;
    }
    // Scans past kMaxRing in one tilt (minutes without a reversal) share the last index, so
    // the cloud stays readable by load_pcd.
    p.ring = static_cast<std::uint16_t>(std::min(b->ring, cloud::kMaxRing));
    p.t = static_cast<float>(tb - b->t0_s);
    b->last_time_s = tb;
    b->points.push_back(p);
    b->spherical.push_back({r, theta_[i], static_cast<float>(phi)});
  }
}

void Assembler::finish_tilt(Building& b, bool ends_at_reversal, std::vector<TiltCloud>& out) {
  TiltStats st;
  st.points = static_cast<std::int64_t>(b.points.size());
  for (const auto& [t, kind] : b.nonpoint) {
    if (kind == kInvalid) ++st.invalid;
    else if (kind == kGap) ++st.dropped_gap;
    else ++st.dropped_no_encoder;
  }
  st.beams = st.points + st.invalid + st.dropped_gap + st.dropped_no_encoder;
  stats_.beams += st.beams;
  stats_.points += st.points;
  stats_.invalid += st.invalid;
  stats_.dropped_gap += st.dropped_gap;
  stats_.dropped_no_encoder += st.dropped_no_encoder;
  if (b.points.empty() && b.nonpoint.empty()) return;

  st.scans = b.points.empty() ? 0 : b.ring + 1;
  if (st.scans < options_.min_scans_per_tilt) {
    ++stats_.tilts_discarded;
    return;
  }
  TiltCloud tc;
  tc.cloud.reset(new cloud::Cloud);
  tc.cloud->points = std::move(b.points);
  tc.cloud->width = static_cast<std::uint32_t>(tc.cloud->points.size());
  tc.cloud->height = 1;
  tc.cloud->is_dense = true;
  tc.spherical = std::move(b.spherical);
  tc.start_time_s = b.t0_s;
  tc.end_time_s = b.last_time_s;
  tc.direction = b.direction;
  tc.partial = !(b.starts_at_reversal && ends_at_reversal);
  tc.stats = st;
  ++stats_.tilts;
  out.push_back(std::move(tc));
}

void Assembler::trim_encoder() {
  // Keep the last sample at or before the oldest time a future scan may still need.
  const double needed_from = scans_.empty() ? last_assembled_scan_s_ : scans_.front().time_s;
  std::size_t k = 0;
  while (k + 1 < encoder_.size() && encoder_[k + 1].time_s <= needed_from && k + 1 <= detector_next_) ++k;
  if (k > 64) {  // erase in batches: deque front erase is cheap but not free
    encoder_.erase(encoder_.begin(), encoder_.begin() + static_cast<std::ptrdiff_t>(k));
    detector_next_ -= k;
  }
}

}  // namespace rgbdt::tilt_lidar
