#include "lidartag/driver/assembly/rotation_assembler.hpp"

#include <algorithm>
#include <cmath>

#include "lidartag/driver/angles.hpp"

namespace lidartag::driver {
namespace {

// A time step this far from the firing period is a discontinuity of the stream (sensor restart,
// replay loop), not loss.
constexpr double kMaxGapUs = 1e6;

}  // namespace

RotationAssembler::RotationAssembler(const SensorLayout& layout, uint8_t return_mode, int returns,
                                     const BatcherOptions& options, ReorderWindow& held,
                                     BatcherStats& stats)
    : layout_(layout),
      mode_(return_mode),
      returns_(returns),
      frame_rule_(layout.delimiter == RotationDelimiter::kFrameId),
      options_(options),
      stats_(stats),
      writer_(held) {}

int RotationAssembler::column_capacity(const SensorLayout& layout) {
  // One rotation at 300 rpm lasts 200 ms; 10 % margin for clock drift and jitter. A frame the
  // sensor announces always fits.
  return std::max(static_cast<int>(std::ceil(1.1 * 200000.0 / layout.column_period_us)),
                  layout.frame_columns);
}

int RotationAssembler::frame_step() const {
  const int bits = std::clamp(layout_.frame_id_bits, 1, 32);
  const uint32_t mask = bits == 32 ? ~0u : (1u << bits) - 1u;
  const uint32_t ahead = (frame_id_ - last_frame_id_) & mask;
  if (ahead > mask / 2) return -1;
  return static_cast<int>(std::min<uint32_t>(ahead, 1u << 30));
}

// Inline: once per column, in classify().
[[gnu::always_inline]] inline bool RotationAssembler::crossed_cut(double from_deg,
                                                                  double to_deg) const {
  // The cut lies in the half-open arc (from, to] travelled clockwise.
  const double step = wrap360(to_deg - from_deg);
  const double to_cut = wrap360(options_.cut_azimuth_deg - from_deg);
  return to_cut > 0 && to_cut <= step;
}

void RotationAssembler::begin(Scan& scan, int64_t stamp_ns) {
  // A fresh scan, or one last filled in another return mode: sized here, once. Lazily: the
  // writer zeroes each column's new storage when it first reaches the column (a scan is sized for
  // 300 rpm, and a short capture may fill a few of its columns).
  if (scan.rings != layout_.rings || scan.returns != returns_ || scan.column_capacity <= 0) {
    scan.reserve_lazily(layout_.rings, returns_, column_capacity(layout_));
  }
  scan.clear();
  scan.sequence = sequence_++;
  scan.model = layout_.model;
  scan.return_mode = mode_;
  scan.starts_at_cut = next_starts_at_cut_;
  scan.stamp_ns = stamp_ns;
  rate_steps_deg_ = 0;
  rate_time_us_ = 0;
  open_ = true;
}

void RotationAssembler::finish(Scan& scan, bool ends_at_cut) {
  writer_.queue_run(scan, open_);
  writer_.write_batch(scan);
  // Columns counted but never written (a packet the writer could not take) read as zero, as in
  // a scan reserved eagerly.
  scan.prepare_columns(scan.columns);
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

bool RotationAssembler::end_stream(Scan& scan) {
  const bool delivered = open_;
  finish(scan, false);
  next_starts_at_cut_ = false;
  have_last_ = false;
  return delivered;
}

void RotationAssembler::forgive_loss(int64_t stamp_ns) {
  for (Gap& g : gaps_) {
    if (g.missing > 0 && stamp_ns > g.from_ns && stamp_ns < g.to_ns) {
      --g.missing;
      if (stats_.missing_packets > 0) --stats_.missing_packets;
      return;
    }
  }
}

// Inline, as follow(): once per column, in run().
[[gnu::always_inline]] inline RotationAssembler::Step RotationAssembler::classify(double az,
                                                                                  int64_t stamp,
                                                                                  int per_packet) {
  Step s;
  const double fp = layout_.column_period_us;
  const double dt = static_cast<double>(stamp - last_column_stamp_ns_) * 1e-3;  // us
  const double step = wrap360(az - last_column_azimuth_);
  const int frames = frame_rule_ && has_frame_ ? frame_step() : 0;
  if (dt <= 0 || dt > kMaxGapUs || frames < 0) {
    // Discontinuity: restart, clock reset, replay loop, a frame counter that went back.
    ++stats_.azimuth_jumps;
    s.jump = true;
    return s;
  }
  // A time gap: compared with the step at the rate of the last normal step (divided only here,
  // not for every column).
  const bool gap = dt > 1.5 * fp;
  const double normal_step = gap ? last_rate_step_deg_ / last_rate_dt_us_ * fp : 0.0;
  // Time and azimuth advanced together, or the frame id skipped frames (whose azimuths repeat):
  // packets were lost on the way.
  const bool lost =
      gap && ((step > 1.5 * normal_step + 0.02 && step < 360.0 - 1.5 * normal_step) || frames > 1);
  if (lost) {
    const double lost_columns = std::max(0.0, std::round(dt / fp) - 1.0);
    s.missing = static_cast<uint32_t>(std::ceil(lost_columns / per_packet));
    stats_.missing_packets += s.missing;
    gaps_[static_cast<size_t>(gap_next_++ % kGaps)] = {last_column_stamp_ns_, stamp, s.missing};
  } else if (gap) {
    // Time gap, azimuth continuous: the sensor paused outside its field of view.
    ++stats_.fov_gaps;
  } else if (step > options_.max_column_step_deg && step < 360.0 - options_.max_column_step_deg) {
    // Azimuth jump without a time gap: restricted field of view (the sensor skips the blanked
    // sector inside a packet).
    ++stats_.fov_gaps;
  } else if (step > 0) {
    rate_steps_deg_ += step;
    rate_time_us_ += dt;
    if (dt > 0.5 * fp) {
      last_rate_step_deg_ = step;
      last_rate_dt_us_ = dt;
    }
  }
  s.cut = frame_rule_ ? frames > 0 : crossed_cut(last_column_azimuth_, az);
  return s;
}

[[gnu::always_inline]] inline void RotationAssembler::follow(double az, int64_t stamp) {
  have_last_ = true;
  last_frame_id_ = frame_id_;
  last_column_azimuth_ = az;
  last_column_stamp_ns_ = stamp;
}

void RotationAssembler::end_before(Scan& scan, int c, double az, int64_t stamp,
                                   uint32_t carried_missing, bool ends_at_cut) {
  finish(scan, ends_at_cut);
  pending_column_ = c;
  pending_missing_ = carried_missing;
  pending_evaluated_ = true;
  follow(az, stamp);
}

bool RotationAssembler::add_packet(const ColumnPacket& pk, int slot, Scan& scan, bool may_end) {
  return run(pk, slot, 0, scan, may_end);
}

void RotationAssembler::resume(const ColumnPacket& pk, int slot, Scan& scan) {
  // The rest of a packet that already ended a rotation: it cannot end another (see run()).
  (void)run(pk, slot, pending_column_, scan, false);
}

bool RotationAssembler::run(const ColumnPacket& pk, int slot, int first, Scan& scan, bool may_end) {
  writer_.start_packet(pk, slot);
  const int per_packet = layout_.packet_columns(pk.returns);
  has_frame_ = pk.has_frame_id;
  frame_id_ = pk.frame_id;
  for (int c = first; c < pk.columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    const double az = pk.column_azimuth_deg[uc];
    const int64_t stamp = pk.stamp_ns + round_half_away(pk.column_time_us[uc] * 1e3);
    Step step;
    if (c == first && pending_evaluated_) {
      // The column that ended the previous rotation: compared with its predecessor already.
      pending_evaluated_ = false;
      step.missing = pending_missing_;
    } else if (have_last_) {
      step = classify(az, stamp, per_packet);
    }
    if (step.jump && !may_end && open_ && stamp < scan.stamp_ns) {
      // Time went back to before the rotation in progress began, where it cannot end (the rest
      // of a stream being closed; only garbage or a replayed packet does this): its columns
      // would precede the rotation's own start. Only a packet's first column can step back (a
      // packet's columns are in firing order), so the whole packet is dropped, as stray.
      ++stats_.inconsistent;
      break;
    }
    if (step.jump || step.cut) {
      if (!open_) {
        if (step.cut) next_starts_at_cut_ = true;
      } else if (may_end) {
        // A loss that straddles the cut leaves both rotations short (a jump has none).
        if (step.jump) ++scan.azimuth_jumps;
        scan.missing_packets += step.missing;
        end_before(scan, c, az, stamp, step.missing, step.cut);
        writer_.end_packet(scan, open_);
        return true;
      }
      // Otherwise a second end inside one packet (azimuths that cross the cut twice, or a cut in
      // the packet that followed a discontinuity): physically a rotation shorter than a packet.
      // The columns stay in the rotation in progress, which did not start at the cut anyway.
    }
    if (!open_) begin(scan, stamp);
    if (scan.columns >= scan.column_capacity) {
      if (may_end) {
        scan.missing_packets += step.missing;
        overflowed_ = true;
        ++stats_.overflows;
        end_before(scan, c, az, stamp, 0, false);
        writer_.end_packet(scan, open_);
        return true;
      }
      // Only with a scan smaller than one packet: the column is lost, counted.
      writer_.queue_run(scan, open_);
      ++stats_.overflows;
      continue;
    }
    scan.missing_packets += step.missing;
    writer_.add_column(c, stamp, scan);
    follow(az, stamp);
  }
  writer_.end_packet(scan, open_);
  return false;
}

}  // namespace lidartag::driver
