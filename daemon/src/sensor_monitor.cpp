#include "lidartag/daemon/sensor_monitor.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include "lidartag/daemon/tap_source.hpp"
#include "lidartag/daemon/time_units.hpp"

namespace lidartag::daemon {

// What the receiving thread knows, copied at every return of CaptureReader::read (each rotation,
// and at least every 100 ms) for the status.
struct SensorMonitor::Snapshot {
  driver::ReaderCounts counts;
  driver::SourceStats source;
  driver::BatcherStats batcher;
  // driver::SensorDescription's views: valid while the reader lives, which outlives the status.
  std::string_view model, mode;
  float rpm = 0;
  int64_t sensor_ns = 0;          // first firing of the last rotation assembled
  uint64_t data_packets = 0;      // data-port packets received (also while the model is probed)
  int64_t last_data_ns = 0;       // steady clock, of the last read that saw new data packets
  std::string model_problem;      // the model decoded does not fit the packets' timing
  std::string model_note;         // CaptureReader::model_mismatch(), once packets contradict it
  std::vector<uint32_t> senders;  // seen within health.window_s
  std::string error;
  std::string source_error;  // why the source ended before its end (set once it ended)
};

// The receiving thread's own: the distinct sender addresses of data packets (per packet one compare
// in the common case; the times are stamped when the snapshot is taken) and the model verdict.
struct SensorMonitor::Senders {
  struct Entry {
    uint32_t address = 0;
    bool seen = false;    // since the last snapshot
    int64_t last_ns = 0;  // steady clock of the snapshot that last saw it
  };
  std::array<Entry, 8> entries{};
  size_t size = 0, last = 0;
  uint64_t data_packets = 0, seen_data = 0;  // data packets, and at the last snapshot
  // The model check's last verdict, and its text (empty: the model fits).
  std::string_view problem_model, problem_timing;
  std::string model_problem;
  uint64_t noted_mismatch = 0;  // CaptureCounts::model_mismatch when model_note was taken
};

SensorMonitor::SensorMonitor(const SensorOptions& sensor, const DaemonOptions& options)
    : sensor_(sensor),
      options_(options),
      data_port_(sensor.source.data_port),
      health_(options.health),
      senders_(std::make_unique<Senders>()),
      snapshot_(std::make_unique<Snapshot>()) {
  snapshot_->senders.reserve(senders_->entries.size());
}

SensorMonitor::~SensorMonitor() = default;

void SensorMonitor::started(int64_t now) {
  started_ns_.store(now);
  receiver_beat_ns_.store(now);
  std::lock_guard lock(counts_mutex_);
  counts_.last_assembled_ns = now;
  counts_.progress_ns = now;
}

// ---- Published by the data path --------------------------------------------------------------

void SensorMonitor::note_sender(const driver::RawPacket& p) {
  if (p.destination_port != data_port_) return;
  Senders& s = *senders_;
  ++s.data_packets;
  if (p.source_ipv4 == 0) return;  // unknown (some replays)
  if (s.size > 0 && s.entries[s.last].address == p.source_ipv4) {
    s.entries[s.last].seen = true;
    return;
  }
  for (size_t i = 0; i < s.size; ++i) {
    if (s.entries[i].address == p.source_ipv4) {
      s.entries[i].seen = true;
      s.last = i;
      return;
    }
  }
  // A new sender; with the table full, the one not seen for the longest time makes room.
  size_t slot = s.size;
  if (s.size == s.entries.size()) {
    slot = 0;
    for (size_t i = 1; i < s.size; ++i) {
      if (s.entries[i].last_ns < s.entries[slot].last_ns) slot = i;
    }
  } else {
    ++s.size;
  }
  s.entries[slot] = {p.source_ipv4, true, 0};
  s.last = slot;
}

void SensorMonitor::after_read(const driver::ScanReader& reader, const Scan* last) {
  const int64_t now = steady_ns();
  Senders& mine = *senders_;
  const driver::ReaderCounts counts = reader.reader_counts();
  // The model decided (configured, or the product byte) against the packets' own evidence (the
  // timing, which follows the latest packets): a wrong configuration or a change mid-stream shows
  // here. The text is made when the verdict changes, not per rotation.
  const driver::SensorDescription d = reader.description();
  const bool mismatch = !d.model.empty() && !d.evidence_fits.empty();
  if (!mismatch) {
    mine.model_problem.clear();
  } else if (mine.problem_model != d.model || mine.problem_timing != d.evidence_fits) {
    mine.model_problem = sensor_.model
                             ? fmt::format(
                                   "configured model {} does not fit the packets (their "
                                   "timing is that of a {}): check sensors[].model",
                                   d.model, d.evidence_fits)
                             : fmt::format(
                                   "decoding as {} (the product byte) but the packets' timing "
                                   "is that of a {}: set sensors[].model",
                                   d.model, d.evidence_fits);
  }
  mine.problem_model = d.model;
  mine.problem_timing = d.evidence_fits;
  std::lock_guard lock(snapshot_mutex_);
  Snapshot& s = *snapshot_;
  s.counts = counts;
  if (mine.data_packets != mine.seen_data) s.last_data_ns = now;
  mine.seen_data = mine.data_packets;
  s.data_packets = mine.data_packets;
  s.source = reader.source_stats();
  s.batcher = reader.batcher_stats();
  s.model = d.model;
  s.mode = d.return_mode;
  s.model_problem = mine.model_problem;  // copied into storage it keeps
  if (counts.model_mismatch != mine.noted_mismatch) {
    s.model_note = reader.mismatch_text();
    mine.noted_mismatch = counts.model_mismatch;
  }
  s.senders.clear();
  for (size_t i = 0; i < mine.size; ++i) {
    auto& e = mine.entries[i];
    if (e.seen) e.last_ns = now;
    e.seen = false;
    if (now - e.last_ns <= nanoseconds(options_.health.window_s)) s.senders.push_back(e.address);
  }
  if (last != nullptr) {
    if (last->rpm > 0) s.rpm = last->rpm;
    s.sensor_ns = last->stamp_ns;
  }
}

void SensorMonitor::receiver_done(std::string source_error, bool stopped) {
  {
    std::lock_guard lock(snapshot_mutex_);
    snapshot_->source_error = std::move(source_error);
  }
  stopped_.store(stopped);
  receiver_done_.store(true, std::memory_order_release);
}

uint64_t SensorMonitor::assembled(int64_t now) {
  std::lock_guard lock(counts_mutex_);
  if (counts_.in_flight++ == 0) counts_.progress_ns = now;
  counts_.last_assembled_ns = now;
  return counts_.assembled++;
}

void SensorMonitor::seam(int64_t now) {
  std::lock_guard lock(counts_mutex_);
  ++counts_.assembled;  // its sequence number is skipped
  ++counts_.seam;
  counts_.last_assembled_ns = now;
}

void SensorMonitor::dropped_behind() {
  std::lock_guard lock(counts_mutex_);
  --counts_.in_flight;
  ++counts_.behind;
}

void SensorMonitor::published(bool sent, size_t detections, int64_t now) {
  std::lock_guard lock(counts_mutex_);
  --counts_.in_flight;
  if (sent) {
    ++counts_.published;
    counts_.detections += detections;
  } else {
    ++counts_.unsent;
  }
  counts_.progress_ns = now;
}

uint64_t SensorMonitor::dropped() const {
  std::lock_guard lock(counts_mutex_);
  return counts_.dropped();
}

void SensorMonitor::fail(const std::string& what) {
  spdlog::error("sensor {}: {}", sensor_.name, what);
  std::lock_guard lock(snapshot_mutex_);
  if (snapshot_->error.empty()) snapshot_->error = what;
}

// ---- Read by the status thread ---------------------------------------------------------------

std::string SensorMonitor::error() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_->error;
}

std::string SensorMonitor::source_error() const {
  std::lock_guard lock(snapshot_mutex_);
  return snapshot_->source_error;
}

std::string SensorMonitor::stall(int64_t now) const {
  const int64_t limit = nanoseconds(options_.watchdog.stall_timeout_s);
  if (!receiver_done_.load(std::memory_order_acquire) &&
      !receiver_waiting_.load(std::memory_order_relaxed)) {
    const int64_t idle = now - receiver_beat_ns_.load(std::memory_order_relaxed);
    if (idle > limit) {
      return fmt::format("the receiving loop has not run for {:.1f} s", seconds(idle));
    }
  }
  std::lock_guard lock(counts_mutex_);
  if (counts_.in_flight > 0 && now - counts_.progress_ns > limit) {
    return fmt::format("no rotation published for {:.1f} s with {} in the pipeline",
                       seconds(now - counts_.progress_ns), counts_.in_flight);
  }
  return {};
}

bool SensorMonitor::progressing(int64_t now, bool finished) const {
  if (finished) return error().empty();
  if (!error().empty() || !stall(now).empty()) return false;
  const int64_t limit = nanoseconds(options_.watchdog.stall_timeout_s);
  {
    std::lock_guard lock(counts_mutex_);
    if (now - counts_.last_assembled_ns <= limit) return true;
  }
  std::lock_guard lock(snapshot_mutex_);
  const Snapshot& s = *snapshot_;
  // Waiting for the sensor to come up.
  if (s.data_packets == 0 &&
      now - started_ns_.load() <= nanoseconds(options_.health.startup_grace_s)) {
    return true;
  }
  // Silent (never a packet past the grace, or none lately): a restart reopens the sockets,
  // unless the sensor is switched off on purpose. Packets without rotations (garbage): no.
  const bool silent =
      s.data_packets == 0 || now - s.last_data_ns > nanoseconds(options_.health.silence_s);
  return silent && options_.watchdog.while_silent;
}

SensorStatus SensorMonitor::status(int64_t now_ns, const PathGauges& gauges) {
  SensorStatus st;
  st.sensor = sensor_.name;
  st.frame_id = sensor_.frame_id;
  HealthSample h;
  h.now_ns = now_ns;
  h.started_ns = started_ns_.load();
  h.ended = gauges.finished;
  h.stopped = stopped_.load();
  h.stall = stall(now_ns);
  h.data_port = data_port_;
  {
    std::lock_guard lock(snapshot_mutex_);
    const Snapshot& s = *snapshot_;
    st.model = std::string(s.model);
    st.return_mode = std::string(s.mode);
    st.rpm = s.rpm;
    st.time_source = s.counts.time_source;
    st.pps = s.counts.pps;
    st.position_packets = s.counts.aux_packets;
    st.gprmc_valid = s.counts.gprmc_valid;
    st.packets_data = s.counts.data_packets;
    st.packets_decoded = s.counts.decoded;
    st.packets_kernel_dropped = s.source.kernel_drops;
    st.packets_missing = s.batcher.missing_packets;
    // `reordered` counts every packet that came after a later one (put in place or dropped);
    // late_packets = duplicates + the reordered ones dropped. (A batcher that does not tell them
    // apart counts every late packet in late_packets only: the difference is then the reorders.)
    st.packets_duplicate = s.batcher.duplicates;
    st.packets_reordered =
        std::max(s.batcher.reordered, s.batcher.late_packets - s.batcher.duplicates);
    st.packets_malformed = s.source.truncated + s.source.malformed + s.counts.refused;
    st.packets_foreign = s.source.foreign_source;
    st.packets_inconsistent = s.batcher.inconsistent;
    st.packets_model_mismatch = s.counts.model_mismatch;
    st.packets_ignored = s.source.ignored;
    st.senders = s.senders;
    st.error = s.error;
    h.error = s.error;
    h.data_packets = s.data_packets;
    h.last_data_ns = s.last_data_ns;
    h.decoded = s.counts.decoded;
    h.malformed = st.packets_malformed;
    h.ignored = s.source.ignored;
    h.foreign = s.source.foreign_source;
    if (h.ended) h.source_error = s.source_error;
    h.missing = s.batcher.missing_packets;
    h.model_mismatch = s.counts.model_mismatch;
    h.rpm = s.rpm;
    h.sensor_ns = s.sensor_ns;
    h.inconsistent = s.batcher.inconsistent;
    h.model_problem = s.model_problem;
    h.model_note = s.model_note;
    h.senders = s.senders;
  }
  st.packets_received = gauges.packets_received;
  {
    std::lock_guard lock(counts_mutex_);
    const RotationCounts& c = counts_;
    st.rotations_assembled = c.assembled;
    st.rotations_published = c.published;
    st.rotations_behind = c.behind;
    st.rotations_seam = c.seam;
    st.rotations_unsent = c.unsent;
    st.rotations_dropped = c.dropped();
    st.rotations_in_flight = c.in_flight;
    st.detections = c.detections;
    h.rotations = c.assembled;
    h.dropped_behind = c.behind;
  }
  st.publish_failures = gauges.publish_failures;
  // Any LCM failure of the bus (the status messages too) means publishing fails now.
  h.publish_failures = std::max<uint64_t>(gauges.bus_failures, st.publish_failures);
  h.size_warnings = gauges.size_warnings;
  h.size_note = gauges.size_note;
  st.health = health_.update(h);
  st.progressing = progressing(now_ns, gauges.finished);
  st.buffer_occupancy = gauges.buffer_waiting;
  st.buffer_depth = gauges.buffer_depth;
  return st;
}

}  // namespace lidartag::daemon
