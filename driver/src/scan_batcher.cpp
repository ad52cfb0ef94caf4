#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::driver {

ScanBatcher::ScanBatcher(const SensorLayout& layout, uint8_t return_mode, int returns,
                         BatcherOptions options)
    : layout_(layout),
      options_(options),
      window_(layout_.max_payload_bytes),
      screen_(layout_, options.flush_timeout_s),
      assembler_(layout_, return_mode, returns, options, window_, stats_),
      stash_(1, layout_.max_payload_bytes) {}

ScanBatcher::~ScanBatcher() = default;

// ---- The one-rotation-per-call rule ----------------------------------------------------------

bool ScanBatcher::catch_up(Scan& scan) {
  if (closing_ && finish_close(scan)) return true;
  if (!stashed_) return false;
  stashed_ = false;
  // add_one() copies what it keeps (window, candidates), so the stash is free again after it.
  return add_one(stash_[0].columns(), scan);
}

bool ScanBatcher::add(const ColumnPacket& pk, Scan& scan) {
  if (catch_up(scan)) {
    // This call delivers already (one rotation per call): the packet waits for the next.
    stash_[0].hold(pk);
    stashed_ = true;
    return true;
  }
  return add_one(pk, scan);
}

bool ScanBatcher::release_held(Scan& scan) {
  if (catch_up(scan)) return true;
  take_pending(scan);
  while (window_.size() > 0)
    if (release_oldest(scan, true)) return true;
  assembler_.write_pending(scan);  // the rotation in progress is up to date in the scan
  return false;
}

bool ScanBatcher::flush(Scan& scan) {
  if (catch_up(scan)) return true;
  take_pending(scan);
  while (window_.size() > 0)
    if (release_oldest(scan, true)) return true;
  // Candidates of a new stream that never got enough company.
  stats_.inconsistent += static_cast<uint64_t>(screen_.clear_candidates());
  return end_stream(scan);
}

bool ScanBatcher::idle(double silent_s, Scan& scan) {
  if (!in_progress()) return false;
  if (silent_s > options_.flush_timeout_s) return flush(scan);
  if (silent_s > ReorderWindow::kReleaseAfter_s) return release_held(scan);
  return false;
}

// ---- A packet: screened, then into the window ------------------------------------------------

bool ScanBatcher::add_one(const ColumnPacket& pk, Scan& scan) {
  if (pk.columns <= 0 || pk.decoder == nullptr) {
    ++stats_.inconsistent;  // not a parsed packet
    return pump(scan);
  }
  bool delivered = false;
  switch (screen_.screen(pk, window_, assembler_.last_column_stamp())) {
    case StreamScreen::Verdict::kDuplicate:
      ++stats_.duplicates;
      ++stats_.late_packets;
      break;
    case StreamScreen::Verdict::kTooLate:
      ++stats_.reordered;
      ++stats_.late_packets;
      assembler_.forgive_loss(pk.stamp_ns);  // it did arrive
      break;
    case StreamScreen::Verdict::kAcceptHeadWasStray:
      // The newest packet taken was a stray one (this one fits the one before it): out it goes.
      ++stats_.inconsistent;
      window_.remove(screen_.head().stamp_ns);
      screen_.drop_head();
      [[fallthrough]];
    case StreamScreen::Verdict::kAccept:
      // The stream is alive: what looked like the start of another one was not.
      stats_.inconsistent += static_cast<uint64_t>(screen_.clear_candidates());
      if (pk.return_mode != assembler_.mode()) {
        if (screen_.has_head() && pk.stamp_ns < screen_.head().stamp_ns) {
          ++stats_.reordered;  // a late packet of the old mode
          ++stats_.late_packets;
          break;
        }
        // Another return mode changes the layout of the scan: close the rotation in progress;
        // this packet starts the next one, in a scan of the new layout.
        screen_.start_candidates(pk);
        delivered = close_stream(scan, false);
        break;
      }
      take(pk);
      break;
    case StreamScreen::Verdict::kSuspect:
      if (screen_.add_candidate(pk) != StreamScreen::Candidate::kHeld) {
        ++stats_.inconsistent;
      } else if (screen_.candidates() == kNewStreamPackets) {
        delivered = adopt_new_stream(scan);
      }
      break;
  }
  if (delivered) return true;
  return pump(scan);
}

void ScanBatcher::take(const ColumnPacket& pk) {
  bool reordered = false;
  if (!window_.insert(pk, reordered)) return;  // cannot happen: pump() keeps it at its depth
  if (reordered) ++stats_.reordered;
  screen_.taken(pk);
}

// ---- The window into the rotation ------------------------------------------------------------

bool ScanBatcher::pump(Scan& scan) {
  take_pending(scan);
  while (window_.size() > kReorderWindow)
    if (release_oldest(scan, true)) return true;
  return false;
}

bool ScanBatcher::release_oldest(Scan& scan, bool may_end) {
  const int slot = window_.pop_oldest();
  const ColumnPacket& pk = window_.packet(slot);
  screen_.released(pk);
  if (assembler_.add_packet(pk, slot, scan, may_end)) {
    pending_slot_ = slot;  // its columns after the end wait for the next scan
    return true;
  }
  done_with(slot);
  return false;
}

void ScanBatcher::take_pending(Scan& scan) {
  if (pending_slot_ < 0) return;
  const int slot = pending_slot_;
  pending_slot_ = -1;
  assembler_.resume(window_.packet(slot), slot, scan);
  done_with(slot);
}

void ScanBatcher::done_with(int slot) {
  // The writer's batch may still read it: freed once the batch is written.
  if (!assembler_.reads(slot)) window_.free(slot);
}

// ---- Streams: ended, and new ones adopted ----------------------------------------------------

bool ScanBatcher::close_stream(Scan& scan, bool jump) {
  closing_ = true;
  closing_jump_ = jump;
  take_pending(scan);
  // The window's packets precede the new stream's: a cut among them ends the rotation as any
  // cut does (a replay's loop seam or a sensor restart right after it loses nothing).
  while (window_.size() > 0)
    if (release_oldest(scan, true)) return true;
  return finish_close(scan);
}

bool ScanBatcher::finish_close(Scan& scan) {
  closing_ = false;
  take_pending(scan);
  // A second cut this close to the first is not a rotation: the columns stay in this one.
  while (window_.size() > 0) (void)release_oldest(scan, false);
  if (closing_jump_) {
    ++stats_.azimuth_jumps;
    if (assembler_.open()) ++scan.azimuth_jumps;
  }
  const bool delivered = end_stream(scan);
  insert_candidates();  // the new stream begins
  return delivered;
}

bool ScanBatcher::end_stream(Scan& scan) {
  screen_.forget_stream();
  return assembler_.end_stream(scan);
}

bool ScanBatcher::adopt_new_stream(Scan& scan) {
  // Several packets agree with each other and none of the old stream came meanwhile. Right after
  // the stream in time: its azimuth jumped (a field of view restricted between packets), the
  // rotation goes on. Otherwise the sensor restarted, its clock jumped or a replay looped.
  const ColumnPacket& first = screen_.candidate(0);
  const double dt_us = static_cast<double>(first.stamp_ns - screen_.head().stamp_ns) * 1e-3;
  const bool continues = screen_.has_head() && dt_us > 0 &&
                         dt_us <= kNewStreamPackets * layout_.packet_period_us(first.returns);
  if (!continues) return close_stream(scan, true);
  insert_candidates();
  return false;
}

void ScanBatcher::insert_candidates() {
  for (int i = 0; i < screen_.candidates(); ++i) {
    const ColumnPacket& pk = screen_.candidate(i);
    if (pk.return_mode != assembler_.mode()) {
      assembler_.set_mode(pk.return_mode, pk.returns);
      ++stats_.mode_changes;
    }
    take(pk);
  }
  (void)screen_.clear_candidates();
}

}  // namespace lidartag::driver
