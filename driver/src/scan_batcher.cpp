#include "lidartag/driver/scan_batcher.hpp"

#include <algorithm>
#include <cmath>

#include "angles.hpp"

namespace lidartag::velodyne {
namespace {

// A time step this far from the firing period is a discontinuity of the stream (sensor restart,
// replay loop), not loss.
constexpr double kMaxGapUs = 1e6;

// Screening: the azimuth a packet must have, predicted from the stream's newest packet, within
// this many degrees, plus this fraction of the predicted travel (rate uncertainty over a gap).
// (In-packet rates are good to about 0.5 %, packet times to 1 us: a stream's own packets land
// within a few hundredths of a degree; a stray packet fits by chance once in several hundred.)
constexpr double kAzimuthToleranceDeg = 0.3;
constexpr double kTravelTolerance = 0.02;
// Packets later than this many packet periods are not reordered ones but foreign.
constexpr double kMaxLatePackets = 16;

// Time of a packet's last column.
int64_t last_stamp(const PacketColumns& pk) {
  const auto last = static_cast<size_t>(std::max(pk.columns - 1, 0));
  return pk.stamp_ns + round_half_away(pk.column_time_us[last] * 1e3);
}

// Signed difference of two azimuths, (-180, 180].
double azimuth_diff(double a, double b) {
  const double d = wrap360(a - b);
  return d > 180.0 ? d - 360.0 : d;
}

}  // namespace

ScanBatcher::ScanBatcher(const ModelSpec& spec, ReturnMode mode, BatcherOptions options)
    : spec_(spec),
      mode_(mode),
      options_(options),
      slots_(std::make_unique<std::array<Held, kSlots>>()),
      candidates_(std::make_unique<std::array<Held, kNewStreamPackets + 1>>()) {}

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
  queue_run(scan);
  write_batch(scan);
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

// ---- Screening: which packets belong to the stream ------------------------------------------

ScanBatcher::Ref ScanBatcher::ref_of(const PacketColumns& pk) {
  const auto last = static_cast<size_t>(std::max(pk.columns - 1, 0));
  // The rate across the whole packet: one column's step (0.2 deg on a VLP-32C, in 0.01 deg
  // steps) is off by up to 5 %, which across a gap of several lost packets misplaces the next
  // packet by more than the tolerance (a lost run would make a good packet look stray).
  float rate = pk.rate_deg[last];
  const double span_us = pk.column_time_us[last] - pk.column_time_us[0];
  if (last > 0 && span_us > 0) {
    const double turned = wrap360(pk.column_azimuth_deg[last] - pk.column_azimuth_deg[0]);
    if (turned < 90.0) rate = static_cast<float>(turned / span_us);
  }
  return {pk.stamp_ns, pk.column_azimuth_deg[0], pk.column_azimuth_deg[last], rate};
}

bool ScanBatcher::fits(const Ref& ref, const PacketColumns& pk) const {
  if (pk.columns <= 0) return false;
  const double dt_us = static_cast<double>(pk.stamp_ns - ref.stamp_ns) * 1e-3;
  const double period_us = spec_.packet_period_us(pk.mode);
  if (dt_us < -kMaxLatePackets * period_us || dt_us > options_.flush_timeout_s * 1e6) return false;
  // Where the sensor pointed at that time, by the rate measured inside the newest packet.
  const double travel = ref.rate_deg_per_us * dt_us;
  const double az = pk.column_azimuth_deg[0];
  if (std::abs(azimuth_diff(az, ref.first_azimuth_deg + travel)) <=
      kAzimuthToleranceDeg + kTravelTolerance * std::abs(travel))
    return true;
  // A restricted field of view: the sensor paused (longer than a packet period), then goes on
  // from where it stopped.
  const double step = ref.rate_deg_per_us * spec_.firing_period_us;
  return dt_us > 1.5 * period_us &&
         std::abs(azimuth_diff(az, ref.last_azimuth_deg + step)) <= kAzimuthToleranceDeg + step;
}

ScanBatcher::Verdict ScanBatcher::screen(const PacketColumns& pk) const {
  if (!have_head_) return Verdict::kAccept;
  const float az = pk.column_azimuth_deg[0];
  // Seen before: in the window, or released not long ago.
  for (int i = 0; i < window_size_; ++i) {
    const PacketColumns& h =
        (*slots_)[static_cast<size_t>(window_[static_cast<size_t>(i)])].columns;
    if (h.stamp_ns == pk.stamp_ns && h.column_azimuth_deg[0] == az) return Verdict::kDuplicate;
  }
  const int remembered = std::min(released_count_, kHistory);
  for (int i = 0; i < remembered; ++i)
    if (released_stamp_[static_cast<size_t>(i)] == pk.stamp_ns &&
        released_azimuth_[static_cast<size_t>(i)] == az)
      return Verdict::kDuplicate;
  if (!fits(head_, pk)) {
    // The newest packet taken may itself have been a stray one that fitted by chance.
    if (have_previous_head_ && pk.stamp_ns > previous_head_.stamp_ns && fits(previous_head_, pk))
      return Verdict::kAcceptHeadWasStray;
    return Verdict::kSuspect;
  }
  // Older than what was already written into the rotation: too late to be put in place.
  if (have_last_ && pk.stamp_ns <= last_column_stamp_ns_) return Verdict::kTooLate;
  // A sensor's packets never overlap in time: one that does is stray, however well it fits.
  const int64_t end = last_stamp(pk);
  for (int i = 0; i < window_size_; ++i) {
    const PacketColumns& h =
        (*slots_)[static_cast<size_t>(window_[static_cast<size_t>(i)])].columns;
    if (pk.stamp_ns <= last_stamp(h) && h.stamp_ns <= end) return Verdict::kSuspect;
  }
  return Verdict::kAccept;
}

void ScanBatcher::hold(const PacketColumns& pk, Held& slot) {
  slot.columns = pk;
  if (pk.payload != nullptr) std::copy_n(pk.payload, kDataPacketSize, slot.bytes.begin());
  slot.columns.payload = slot.bytes.data();
}

void ScanBatcher::insert(const PacketColumns& pk) {
  int slot = 0;
  while (slot < kSlots && busy_[static_cast<size_t>(slot)]) ++slot;
  if (slot == kSlots) return;  // cannot happen: pump() keeps the window below its slots
  busy_[static_cast<size_t>(slot)] = true;
  hold(pk, (*slots_)[static_cast<size_t>(slot)]);
  // Sorted by time, oldest first; a packet placed before a later one arrived out of order.
  int i = window_size_;
  while (i > 0 &&
         (*slots_)[static_cast<size_t>(window_[static_cast<size_t>(i - 1)])].columns.stamp_ns >
             pk.stamp_ns) {
    window_[static_cast<size_t>(i)] = window_[static_cast<size_t>(i - 1)];
    --i;
  }
  if (i < window_size_) ++stats_.reordered;
  window_[static_cast<size_t>(i)] = slot;
  ++window_size_;
  if (!have_head_ || pk.stamp_ns > head_.stamp_ns) {
    previous_head_ = head_;
    have_previous_head_ = have_head_;
    head_ = ref_of(pk);
  }
  have_head_ = true;
  last_packet_stamp_ns_ = std::max(last_packet_stamp_ns_, pk.stamp_ns);
}

void ScanBatcher::drop_stray_head() {
  ++stats_.inconsistent;
  for (int i = 0; i < window_size_; ++i) {
    const int slot = window_[static_cast<size_t>(i)];
    if ((*slots_)[static_cast<size_t>(slot)].columns.stamp_ns != head_.stamp_ns) continue;
    std::copy(window_.begin() + i + 1, window_.begin() + window_size_, window_.begin() + i);
    --window_size_;
    busy_[static_cast<size_t>(slot)] = false;
    break;
  }
  head_ = previous_head_;
  have_previous_head_ = false;
}

void ScanBatcher::forgive_gap(int64_t stamp_ns) {
  for (Gap& g : gaps_) {
    if (g.missing > 0 && stamp_ns > g.from_ns && stamp_ns < g.to_ns) {
      --g.missing;
      if (stats_.missing_packets > 0) --stats_.missing_packets;
      return;
    }
  }
}

bool ScanBatcher::catch_up(Scan& scan) {
  if (closing_ && finish_close(scan)) return true;
  if (!stashed_) return false;
  stashed_ = false;
  // add_one() copies what it keeps (window, candidates), so the stash is free again after it.
  return add_one((*candidates_)[kNewStreamPackets].columns, scan);
}

bool ScanBatcher::add(const PacketColumns& pk, Scan& scan) {
  if (catch_up(scan)) {
    // This call delivers already (one rotation per call): the packet waits for the next.
    hold(pk, (*candidates_)[kNewStreamPackets]);
    stashed_ = true;
    return true;
  }
  return add_one(pk, scan);
}

bool ScanBatcher::add_one(const PacketColumns& pk, Scan& scan) {
  if (pk.columns <= 0 || pk.decoder == nullptr) {
    ++stats_.inconsistent;  // not a parsed packet
    return pump(scan);
  }
  bool delivered = false;
  switch (screen(pk)) {
    case Verdict::kDuplicate:
      ++stats_.duplicates;
      ++stats_.late_packets;
      break;
    case Verdict::kTooLate:
      ++stats_.reordered;
      ++stats_.late_packets;
      forgive_gap(pk.stamp_ns);  // it did arrive
      break;
    case Verdict::kAcceptHeadWasStray:
      drop_stray_head();
      [[fallthrough]];
    case Verdict::kAccept:
      // The stream is alive: what looked like the start of another one was not.
      stats_.inconsistent += static_cast<uint64_t>(candidate_count_);
      candidate_count_ = 0;
      if (pk.mode != mode_) {
        if (have_head_ && pk.stamp_ns < head_.stamp_ns) {  // a late packet of the old mode
          ++stats_.reordered;
          ++stats_.late_packets;
          break;
        }
        // Another return mode changes the layout of the scan: close the rotation in progress;
        // this packet starts the next one, in a scan of the new layout.
        hold(pk, (*candidates_)[0]);
        candidate_count_ = 1;
        delivered = close_stream(scan, false);
        break;
      }
      insert(pk);
      break;
    case Verdict::kSuspect: {
      auto& c = *candidates_;
      if (candidate_count_ == 0 ||
          fits(ref_of(c[static_cast<size_t>(candidate_count_ - 1)].columns), pk)) {
        hold(pk, c[static_cast<size_t>(candidate_count_++)]);
        if (candidate_count_ == kNewStreamPackets) delivered = adopt_new_stream(scan);
      } else if (candidate_count_ == 1) {
        // One odd packet then another that disagrees with it: the first was the stray one.
        ++stats_.inconsistent;
        hold(pk, c[0]);
      } else {
        ++stats_.inconsistent;
      }
      break;
    }
  }
  if (delivered) return true;
  return pump(scan);
}

bool ScanBatcher::close_stream(Scan& scan, bool jump) {
  closing_ = true;
  closing_jump_ = jump;
  take_pending(scan);
  // The window's packets precede the new stream's: a cut among them ends the rotation as any
  // cut does (a replay's loop seam or a sensor restart right after it loses nothing).
  while (window_size_ > 0)
    if (release_oldest(scan, true)) return true;
  return finish_close(scan);
}

bool ScanBatcher::finish_close(Scan& scan) {
  closing_ = false;
  take_pending(scan);
  // A second cut this close to the first is not a rotation: the columns stay in this one.
  while (window_size_ > 0) (void)release_oldest(scan, false);
  if (closing_jump_) {
    ++stats_.azimuth_jumps;
    if (open_) ++scan.azimuth_jumps;
  }
  const bool delivered = end_stream(scan);
  insert_candidates();  // the new stream begins
  return delivered;
}

bool ScanBatcher::end_stream(Scan& scan) {
  const bool delivered = open_;
  finish(scan, false);
  next_starts_at_cut_ = false;
  have_last_ = false;
  have_head_ = have_previous_head_ = false;
  return delivered;
}

bool ScanBatcher::adopt_new_stream(Scan& scan) {
  // Several packets agree with each other and none of the old stream came meanwhile. Right after
  // the stream in time: its azimuth jumped (a field of view restricted between packets), the
  // rotation goes on. Otherwise the sensor restarted, its clock jumped or a replay looped.
  const PacketColumns& first = (*candidates_)[0].columns;
  const double dt_us = static_cast<double>(first.stamp_ns - head_.stamp_ns) * 1e-3;
  const bool continues =
      have_head_ && dt_us > 0 && dt_us <= kNewStreamPackets * spec_.packet_period_us(first.mode);
  if (!continues) return close_stream(scan, true);
  insert_candidates();
  return false;
}

void ScanBatcher::insert_candidates() {
  const int n = candidate_count_;
  candidate_count_ = 0;
  for (int i = 0; i < n; ++i) {
    const PacketColumns& pk = (*candidates_)[static_cast<size_t>(i)].columns;
    if (pk.mode != mode_) {
      mode_ = pk.mode;
      ++stats_.mode_changes;
    }
    insert(pk);
  }
}

bool ScanBatcher::pump(Scan& scan) {
  take_pending(scan);
  while (window_size_ > kReorderWindow)
    if (release_oldest(scan, true)) return true;
  return false;
}

bool ScanBatcher::release_oldest(Scan& scan, bool may_end) {
  const int slot = window_[0];
  std::copy(window_.begin() + 1, window_.begin() + window_size_, window_.begin());
  --window_size_;
  const PacketColumns& pk = (*slots_)[static_cast<size_t>(slot)].columns;
  const auto h = static_cast<size_t>(released_count_++ % kHistory);
  released_stamp_[h] = pk.stamp_ns;
  released_azimuth_[h] = pk.column_azimuth_deg[0];
  packet_slot_ = slot;
  const bool ended = run(pk, 0, scan, may_end);
  packet_slot_ = -1;
  if (ended) {
    pending_slot_ = slot;  // its columns after the end wait for the next scan
    return true;
  }
  done_with(slot);
  return false;
}

void ScanBatcher::done_with(int slot) {
  for (int i = 0; i < batch_slot_count_; ++i)
    if (batch_slots_[static_cast<size_t>(i)] == slot) return;  // freed once the batch is written
  busy_[static_cast<size_t>(slot)] = false;
}

void ScanBatcher::take_pending(Scan& scan) {
  if (pending_slot_ < 0) return;
  const int slot = pending_slot_;
  pending_slot_ = -1;
  // The rest of a packet that already ended a rotation: it cannot end another (see run()).
  packet_slot_ = slot;
  (void)run((*slots_)[static_cast<size_t>(slot)].columns, pending_column_, scan, false);
  packet_slot_ = -1;
  done_with(slot);
}

bool ScanBatcher::release_held(Scan& scan) {
  if (catch_up(scan)) return true;
  take_pending(scan);
  while (window_size_ > 0)
    if (release_oldest(scan, true)) return true;
  write_batch(scan);  // the rotation in progress is up to date in the scan
  return false;
}

bool ScanBatcher::flush(Scan& scan) {
  if (catch_up(scan)) return true;
  take_pending(scan);
  while (window_size_ > 0)
    if (release_oldest(scan, true)) return true;
  // Candidates of a new stream that never got enough company.
  stats_.inconsistent += static_cast<uint64_t>(candidate_count_);
  candidate_count_ = 0;
  return end_stream(scan);
}

bool ScanBatcher::poll(int64_t now_ns, Scan& scan) {
  if (in_progress() &&
      static_cast<double>(now_ns - last_packet_stamp_ns_) > options_.flush_timeout_s * 1e9) {
    return flush(scan);
  }
  return false;
}

// ---- Assembly: released packets into the scan ----------------------------------------------

bool ScanBatcher::run(const PacketColumns& pk, int first, Scan& scan, bool may_end) {
  packet_ = &pk;
  const double fp = spec_.firing_period_us;
  const int per_packet = spec_.columns_per_packet(pk.mode);
  for (int c = first; c < pk.columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    const double az = pk.column_azimuth_deg[uc];
    const int64_t stamp = pk.stamp_ns + round_half_away(pk.column_time_us[uc] * 1e3);
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
        // A time gap: compared with the step at the rate of the last normal step (divided only
        // here, not for every column).
        const bool gap = dt > 1.5 * fp;
        const double normal_step = gap ? last_rate_step_deg_ / last_rate_dt_us_ * fp : 0.0;
        if (gap && step > 1.5 * normal_step + 0.02 && step < 360.0 - 1.5 * normal_step) {
          // Time and azimuth advanced together: packets were lost on the way.
          const double lost_columns = std::max(0.0, std::round(dt / fp) - 1.0);
          missing = static_cast<uint32_t>(std::ceil(lost_columns / per_packet));
          stats_.missing_packets += missing;
          gaps_[static_cast<size_t>(gap_next_++ % kGaps)] = {last_column_stamp_ns_, stamp, missing};
        } else if (gap) {
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
          if (dt > 0.5 * fp) {
            last_rate_step_deg_ = step;
            last_rate_dt_us_ = dt;
          }
        }
        cut = crossed_cut(last_column_azimuth_, az);
      }
    }
    if (jump && !may_end && open_ && stamp < scan.stamp_ns) {
      // Time went back to before the rotation in progress began, where it cannot end (the rest
      // of a stream being closed; only garbage or a replayed packet does this): its columns
      // would precede the rotation's own start. Only a packet's first column can step back (a
      // packet's columns are in firing order), so the whole packet is dropped, as stray.
      ++stats_.inconsistent;
      break;
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
        pending_column_ = c;
        pending_missing_ = missing;
        pending_evaluated_ = true;
        have_last_ = true;
        last_column_azimuth_ = az;
        last_column_stamp_ns_ = stamp;
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
        pending_column_ = c;
        pending_missing_ = 0;
        pending_evaluated_ = true;
        have_last_ = true;
        last_column_azimuth_ = az;
        last_column_stamp_ns_ = stamp;
        packet_ = nullptr;
        return true;
      }
      // Only with a scan smaller than one packet: the column is lost, counted.
      queue_run(scan);
      ++stats_.overflows;
      continue;
    }
    scan.missing_packets += missing;
    add_column(pk, c, stamp, scan);
    have_last_ = true;
    last_column_azimuth_ = az;
    last_column_stamp_ns_ = stamp;
  }
  queue_run(scan);
  packet_ = nullptr;
  return false;
}

void ScanBatcher::add_column(const PacketColumns& pk, int c, int64_t stamp, Scan& s) {
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

void ScanBatcher::queue_run(Scan& s) {
  if (run_columns_ == 0 || !open_ || packet_ == nullptr) {
    run_columns_ = 0;
    return;
  }
  const PacketColumns& pk = *packet_;
  const int n = run_columns_;
  run_columns_ = 0;
  if (pk.rings != s.rings || pk.decoder == nullptr) return;  // cannot happen: begin() sized it
  const auto t_off = static_cast<float>(run_time_offset_s_);
  // Runs go to consecutive scan columns; one that does not (a column lost to a full scan) or
  // does not fit starts a new batch.
  if (batch_.columns > 0 && (run_scan_column_ != batch_column_ + batch_.columns ||
                             !batch_.append(pk, run_packet_column_, n, t_off))) {
    write_batch(s);
  }
  if (batch_.columns == 0) {
    batch_column_ = run_scan_column_;
    (void)batch_.append(pk, run_packet_column_, n, t_off);
  }
  if (packet_slot_ >= 0 &&
      (batch_slot_count_ == 0 ||
       batch_slots_[static_cast<size_t>(batch_slot_count_ - 1)] != packet_slot_))
    batch_slots_[static_cast<size_t>(batch_slot_count_++)] = packet_slot_;
  decoder_ = pk.decoder;
  if (batch_.columns >= kBatchColumns) write_batch(s);
}

void ScanBatcher::write_batch(Scan& s) {
  const int n = batch_.columns;
  if (n > 0 && decoder_ != nullptr && batch_.returns <= s.returns &&
      batch_column_ + n <= s.column_capacity) {
    // The decoder writes the batch straight into the scan's ring-major storage.
    const size_t cell = s.at(0, 0, batch_column_);
    const auto ring_stride = static_cast<size_t>(s.column_capacity);
    const PointSink sink{s.x.data() + cell,
                         s.y.data() + cell,
                         s.z.data() + cell,
                         s.range.data() + cell,
                         s.azimuth_deg.data() + cell,
                         s.time_s.data() + cell,
                         s.intensity.data() + cell,
                         s.return_type.data() + cell,
                         ring_stride,
                         ring_stride * static_cast<size_t>(s.rings),
                         0.0f,
                         1e-6f};
    decoder_->write_batch(batch_, sink);
    for (int r = batch_.returns; r < s.returns; ++r) {  // single-return packets, dual scan
      for (int ring = 0; ring < s.rings; ++ring) {
        const auto dst = static_cast<std::ptrdiff_t>(s.at(r, ring, batch_column_));
        std::fill_n(s.range.begin() + dst, n, 0.0f);
        std::fill_n(s.return_type.begin() + dst, n, ReturnType::kNone);
      }
    }
  } else if (n > 0 && batch_column_ + n <= s.column_capacity) {
    // Columns the decoder cannot write here (dual-return packets in a single-return scan: a new
    // stream whose first packets mixed modes, counted in mode_changes) hold no return rather
    // than what the scan held before: a scan's storage is reused without being cleared.
    for (int r = 0; r < s.returns; ++r)
      for (int ring = 0; ring < s.rings; ++ring) {
        const auto dst = static_cast<std::ptrdiff_t>(s.at(r, ring, batch_column_));
        std::fill_n(s.range.begin() + dst, n, 0.0f);
        std::fill_n(s.return_type.begin() + dst, n, ReturnType::kNone);
      }
  }
  batch_.columns = 0;
  // The held packets the batch read are free now, but the one being run.
  for (int i = 0; i < batch_slot_count_; ++i) {
    const int slot = batch_slots_[static_cast<size_t>(i)];
    if (slot != packet_slot_ && slot != pending_slot_) busy_[static_cast<size_t>(slot)] = false;
  }
  batch_slot_count_ = 0;
}

}  // namespace lidartag::velodyne
