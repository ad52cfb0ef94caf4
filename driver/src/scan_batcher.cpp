#include "lidartag/driver/scan_batcher.hpp"

#include <algorithm>
#include <cmath>

#include "angles.hpp"

namespace lidartag::velodyne {
namespace {

// A time step this far from the firing period is a discontinuity of the stream (sensor restart,
// replay loop), not loss.
constexpr double kMaxGapUs = 1e6;

// n consecutive cells of one ring from a packet into a scan. Plain restrict pointers so that the
// compiler neither reloads the vectors' data pointers after every store nor assumes aliasing.
void copy_cells(const DecodedPacket& pk, size_t src, Scan& s, size_t dst, int n, float t_off) {
  const float* __restrict px = pk.x.data() + src;
  const float* __restrict py = pk.y.data() + src;
  const float* __restrict pz = pk.z.data() + src;
  const float* __restrict pr = pk.range.data() + src;
  const float* __restrict pa = pk.azimuth_deg.data() + src;
  const float* __restrict pt = pk.time_us.data() + src;
  const uint8_t* __restrict pi = pk.intensity.data() + src;
  const ReturnType* __restrict pty = pk.return_type.data() + src;
  float* __restrict sx = s.x.data() + dst;
  float* __restrict sy = s.y.data() + dst;
  float* __restrict sz = s.z.data() + dst;
  float* __restrict sr = s.range.data() + dst;
  float* __restrict sa = s.azimuth_deg.data() + dst;
  float* __restrict st = s.time_s.data() + dst;
  uint8_t* __restrict si = s.intensity.data() + dst;
  ReturnType* __restrict sty = s.return_type.data() + dst;
  // The 8 x rings destination streams are too many for the hardware prefetcher: ask for the
  // line the next packet's columns will land in now, so its fetch overlaps this packet's work.
  for (float* p : {sx, sy, sz, sr, sa, st}) __builtin_prefetch(p + n + 16, 1);
  __builtin_prefetch(si + n + 64, 1);
  __builtin_prefetch(sty + n + 64, 1);
  for (int k = 0; k < n; ++k) {
    sx[k] = px[k];
    sy[k] = py[k];
    sz[k] = pz[k];
    sr[k] = pr[k];
    sa[k] = pa[k];
    st[k] = t_off + pt[k] * 1e-6f;
    si[k] = pi[k];
    sty[k] = pty[k];
  }
}

}  // namespace

ScanBatcher::ScanBatcher(const ModelSpec& spec, ReturnMode mode, BatcherOptions options)
    : spec_(spec), mode_(mode), options_(options), stash_(std::make_unique<DecodedPacket>()) {}

ScanBatcher::~ScanBatcher() = default;

int ScanBatcher::column_capacity(const ModelSpec& spec) {
  // One rotation at 300 rpm lasts 200 ms; 10 % margin for clock drift and jitter.
  return static_cast<int>(std::ceil(1.1 * 200000.0 / spec.firing_period_us));
}

bool ScanBatcher::crossed_cut(double from_deg, double to_deg) const {
  // The cut lies in the half-open arc (from, to] travelled clockwise.
  const double step = wrap360(to_deg - from_deg);
  const double to_cut = wrap360(options_.cut_azimuth_deg - from_deg);
  return to_cut > 0 && to_cut <= step;
}

void ScanBatcher::begin(Scan& scan, int64_t stamp_ns) {
  const int returns = mode_ == ReturnMode::kDual ? 2 : 1;
  // A fresh scan, or one last filled in another return mode: sized here, once.
  if (scan.rings != spec_.lasers || scan.returns != returns || scan.column_capacity <= 0) {
    scan.reserve(spec_.lasers, returns, column_capacity(spec_));
  }
  scan.clear();
  scan.sequence = sequence_++;
  scan.model = static_cast<uint8_t>(spec_.model);
  scan.return_mode = static_cast<uint8_t>(mode_);
  scan.starts_at_cut = next_starts_at_cut_;
  scan.stamp_ns = stamp_ns;
  rate_steps_deg_ = 0;
  rate_time_us_ = 0;
  open_ = true;
}

void ScanBatcher::finish(Scan& scan, bool ends_at_cut) {
  copy_run(scan);
  next_starts_at_cut_ = ends_at_cut;
  if (!open_) return;
  open_ = false;
  scan.ends_at_cut = ends_at_cut;
  scan.complete =
      scan.starts_at_cut && scan.ends_at_cut && scan.missing_packets == 0 && !overflowed_;
  if (rate_time_us_ > 0) {
    scan.rpm = static_cast<float>(rate_steps_deg_ / rate_time_us_ * 1e6 / 6.0);
  }
  overflowed_ = false;
  ++stats_.rotations;
  ++(scan.complete ? stats_.complete : stats_.incomplete);
}

void ScanBatcher::keep(const DecodedPacket& pk, int column, uint32_t missing, bool evaluated) {
  // Once per rotation: the copy of one packet is small next to a rotation.
  if (&pk != stash_.get()) *stash_ = pk;
  pending_ = true;
  pending_column_ = column;
  pending_missing_ = missing;
  pending_evaluated_ = evaluated;
}

void ScanBatcher::take_pending(Scan& scan) {
  if (!pending_) return;
  pending_ = false;
  // The rest of a packet that already ended a rotation: it cannot end another (see run()).
  (void)run(*stash_, pending_column_, scan, false);
}

bool ScanBatcher::flush(Scan& scan) {
  take_pending(scan);
  const bool delivered = open_;
  finish(scan, false);
  next_starts_at_cut_ = false;
  have_last_ = false;
  return delivered;
}

bool ScanBatcher::poll(int64_t now_ns, Scan& scan) {
  if (in_progress() &&
      static_cast<double>(now_ns - last_packet_stamp_ns_) > options_.flush_timeout_s * 1e9) {
    return flush(scan);
  }
  return false;
}

bool ScanBatcher::add(const DecodedPacket& pk, Scan& scan) {
  take_pending(scan);
  if (pk.mode != mode_) {
    // Another return mode changes the layout of the scan: close the rotation in progress, and
    // start the next one with this packet, in a scan of the new layout.
    const bool delivered = open_;
    finish(scan, false);
    next_starts_at_cut_ = false;
    have_last_ = false;
    mode_ = pk.mode;
    ++stats_.mode_changes;
    if (delivered) {
      last_packet_stamp_ns_ = pk.stamp_ns;
      keep(pk, 0, 0, true);
      return true;
    }
  }
  if (have_last_ && pk.stamp_ns <= last_column_stamp_ns_ &&
      static_cast<double>(last_column_stamp_ns_ - pk.stamp_ns) < kMaxGapUs * 1e3) {
    // A duplicate, or a packet overtaken by a later one (whose gap was already counted).
    ++stats_.late_packets;
    return false;
  }
  last_packet_stamp_ns_ = pk.stamp_ns;
  return run(pk, 0, scan, true);
}

bool ScanBatcher::run(const DecodedPacket& pk, int first, Scan& scan, bool may_end) {
  packet_ = &pk;
  const double fp = spec_.firing_period_us;
  const int per_packet = spec_.columns_per_packet(pk.mode);
  for (int c = first; c < pk.columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    const double az = pk.column_azimuth_deg[uc];
    const int64_t stamp =
        pk.stamp_ns + static_cast<int64_t>(std::llround(pk.column_time_us[uc] * 1e3));
    uint32_t missing = 0;
    bool cut = false, jump = false;
    if (c == first && pending_evaluated_) {
      // The column that ended the previous rotation: compared with its predecessor already.
      pending_evaluated_ = false;
      missing = pending_missing_;
    } else if (have_last_) {
      const double dt = static_cast<double>(stamp - last_column_stamp_ns_) * 1e-3;  // us
      const double step = wrap360(az - last_column_azimuth_);
      if (dt <= 0 || dt > kMaxGapUs) {
        // Discontinuity: restart, clock reset or replay loop.
        ++stats_.azimuth_jumps;
        jump = true;
      } else {
        const double rate = last_rate_deg_per_us_;
        const double normal_step = rate * fp;
        if (dt > 1.5 * fp && step > 1.5 * normal_step + 0.02 && step < 360.0 - 1.5 * normal_step) {
          // Time and azimuth advanced together: packets were lost on the way.
          const double lost_columns = std::max(0.0, std::round(dt / fp) - 1.0);
          missing = static_cast<uint32_t>(std::ceil(lost_columns / per_packet));
          stats_.missing_packets += missing;
        } else if (dt > 1.5 * fp) {
          // Time gap, azimuth continuous: the sensor paused outside its field of view.
          ++stats_.fov_gaps;
        } else if (step > options_.max_column_step_deg &&
                   step < 360.0 - options_.max_column_step_deg) {
          // Azimuth jump without a time gap: restricted field of view (the sensor skips the
          // blanked sector inside a packet).
          ++stats_.fov_gaps;
        } else if (step > 0) {
          rate_steps_deg_ += step;
          rate_time_us_ += dt;
          if (dt > 0.5 * fp) last_rate_deg_per_us_ = step / dt;
        }
        cut = crossed_cut(last_column_azimuth_, az);
      }
    }
    if (jump || cut) {
      if (!open_) {
        if (cut) next_starts_at_cut_ = true;
      } else if (may_end) {
        if (jump) {
          ++scan.azimuth_jumps;
        } else {
          // A loss that straddles the cut leaves both rotations short.
          scan.missing_packets += missing;
        }
        finish(scan, cut);
        keep(pk, c, missing, true);
        packet_ = nullptr;
        return true;
      }
      // Otherwise a second end inside one packet (azimuths that cross the cut twice, or a cut in
      // the packet that followed a discontinuity): physically a rotation shorter than a packet.
      // The columns stay in the rotation in progress, which did not start at the cut anyway.
    }
    if (!open_) begin(scan, stamp);
    if (scan.columns >= scan.column_capacity) {
      if (may_end) {
        scan.missing_packets += missing;
        overflowed_ = true;
        ++stats_.overflows;
        finish(scan, false);
        keep(pk, c, 0, true);
        packet_ = nullptr;
        return true;
      }
      // Only with a scan smaller than one packet: the column is lost, counted.
      copy_run(scan);
      ++stats_.overflows;
      continue;
    }
    scan.missing_packets += missing;
    add_column(pk, c, stamp, scan);
    have_last_ = true;
    last_column_azimuth_ = az;
    last_column_stamp_ns_ = stamp;
  }
  copy_run(scan);
  packet_ = nullptr;
  return false;
}

void ScanBatcher::add_column(const DecodedPacket& pk, int c, int64_t stamp, Scan& s) {
  const int col = s.columns++;
  const auto ucol = static_cast<size_t>(col);
  const double t0 = static_cast<double>(stamp - s.stamp_ns) * 1e-9;  // column start from scan start
  s.column_azimuth_deg[ucol] = pk.column_azimuth_deg[static_cast<size_t>(c)];
  s.column_time_s[ucol] = t0;
  if (col == 0) {
    ++s.packets;
    if (pk.laser_of_ring != nullptr)
      std::copy_n(pk.laser_of_ring, std::min(s.rings, pk.rings), s.laser_id.begin());
  }
  if (c == 0 && col > 0) ++s.packets;
  if (run_columns_ == 0) {
    run_packet_column_ = c;
    run_scan_column_ = col;
    // The packet's firing times are relative to its first column; the scan's to its own start.
    run_time_offset_s_ = t0 - pk.column_time_us[static_cast<size_t>(c)] * 1e-6;
  }
  ++run_columns_;
}

void ScanBatcher::copy_run(Scan& s) {
  if (run_columns_ == 0 || !open_ || packet_ == nullptr) {
    run_columns_ = 0;
    return;
  }
  const DecodedPacket& pk = *packet_;
  const int n = run_columns_;
  run_columns_ = 0;
  const int rings = std::min(s.rings, pk.rings);
  const auto t_off = static_cast<float>(run_time_offset_s_);
  // Both layouts are ring-major: each ring's columns are one contiguous run on either side.
  for (int r = 0; r < s.returns; ++r) {
    for (int ring = 0; ring < rings; ++ring) {
      const size_t dst = s.at(r, ring, run_scan_column_);
      if (r >= pk.returns) {  // a single-return packet in a dual-return scan
        std::fill_n(s.range.begin() + static_cast<std::ptrdiff_t>(dst), n, 0.0f);
        std::fill_n(s.return_type.begin() + static_cast<std::ptrdiff_t>(dst), n, ReturnType::kNone);
        continue;
      }
      const auto src = static_cast<size_t>(pk.at(r, run_packet_column_, ring));
      copy_cells(pk, src, s, dst, n, t_off);
    }
  }
}

}  // namespace lidartag::velodyne
