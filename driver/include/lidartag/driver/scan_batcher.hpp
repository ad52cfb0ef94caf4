// Decoded packets -> whole rotations, cut at a configurable azimuth at the column (firing) level.
// A small functor: the caller owns the scans and passes the one to fill with every packet; the
// batcher assembles straight into it (no second copy). Design notes: docs/scan-assembly.md.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "lidartag/driver/decoder.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/sensor_model.hpp"

namespace lidartag::velodyne {

struct BatcherOptions {
  // Rotations are cut where the firing azimuth crosses this angle (degrees, 0 = straight ahead,
  // clockwise seen from above). The default cuts behind the sensor, where its cable usually is,
  // so nothing in front is split between two rotations.
  double cut_azimuth_deg = 180.0;
  // A rotation in progress is delivered (incomplete) when no packet arrived for this long.
  double flush_timeout_s = 0.25;
  // An azimuth step larger than this between consecutive columns without a time gap is the
  // blanked sector of a restricted field of view (counted in fov_gaps, the rotation goes on), not
  // lost packets. A time step of a second or more, or backwards, is a jump (restart).
  double max_column_step_deg = 5.0;
};

struct BatcherStats {
  uint64_t rotations = 0;   // delivered
  uint64_t complete = 0;    // of which complete
  uint64_t incomplete = 0;  // partial first/last, loss, jumps, timeouts
  // Packets that never arrived (gaps in the packet times). A packet counted here that turns up
  // later, too late to be put in place, is taken out again (and counted in `reordered`).
  uint64_t missing_packets = 0;
  uint64_t azimuth_jumps = 0;  // discontinuities of the stream (restart, clock jump, replay loop)
  uint64_t fov_gaps = 0;       // gaps recognised as a restricted field of view
  uint64_t overflows = 0;      // rotations cut because the scan was full
  uint64_t mode_changes = 0;
  // Every data packet added is used, or counted in exactly one of duplicates, reordered (when
  // too late to be put in place) and inconsistent.
  uint64_t duplicates = 0;  // same time and azimuth as a packet already taken: dropped
  // Arrived after a later packet: put in place by the reorder window, or dropped when it came
  // later than the window allows (those are in late_packets too).
  uint64_t reordered = 0;
  uint64_t late_packets = 0;  // dropped for coming late: duplicates + reordered ones dropped
  // Time or azimuth contradicts the stream (spoofed, another sensor, garbage): dropped without
  // cutting or ending the rotation.
  uint64_t inconsistent = 0;

  // Field by field: the counts of two batchers of one stream (a model change makes a new one).
  BatcherStats& operator+=(const BatcherStats& o) {
    rotations += o.rotations;
    complete += o.complete;
    incomplete += o.incomplete;
    missing_packets += o.missing_packets;
    azimuth_jumps += o.azimuth_jumps;
    fov_gaps += o.fov_gaps;
    overflows += o.overflows;
    mode_changes += o.mode_changes;
    duplicates += o.duplicates;
    reordered += o.reordered;
    late_packets += o.late_packets;
    inconsistent += o.inconsistent;
    return *this;
  }
};

class ScanBatcher {
 public:
  // Packets held back to put reordered ones in place: a rotation is delivered this many packet
  // periods after its last packet (VLP-16: 5.3 ms, VLS-128: 0.7 ms).
  static constexpr int kReorderWindow = 4;
  // Consecutive packets that agree with each other but not with the stream, with no packet of
  // the stream in between, that make a new stream (restart, clock jump, replay loop).
  static constexpr int kNewStreamPackets = 3;

  ScanBatcher(const ModelSpec& spec, ReturnMode mode, BatcherOptions options);
  ~ScanBatcher();
  ScanBatcher(const ScanBatcher&) = delete;
  ScanBatcher& operator=(const ScanBatcher&) = delete;

  // Adds one packet (parsed or decoded: its columns are written straight into the scan by the
  // decoder that parsed it, which must outlive this batcher's use of it). Returns true when
  // `scan` holds a finished rotation (complete or not: Scan::complete); columns after the cut are
  // kept and go first into the next scan passed in, which must then be another one (or this one,
  // once the caller is done with it). While it returns false, pass the same scan again: it holds
  // the rotation in progress. A call ends at most one rotation. A scan whose shape (rings,
  // returns) does not fit is reserved for the model when its rotation begins (first use,
  // return-mode change): a scan may start empty. Never throws, never allocates.
  [[nodiscard]] bool add(const PacketColumns& packet, Scan& scan);
  // The stream ended: delivers what is held back and the rotation in progress (incomplete), one
  // rotation per call: call again while it returns true.
  [[nodiscard]] bool flush(Scan& scan);
  // The source paused (no packet to reorder is coming): the packets held back go into the
  // rotation, which goes on. True when that ended a rotation (call again: one per call).
  [[nodiscard]] bool release_held(Scan& scan);
  // flush() when the newest packet is older than flush_timeout_s; `now_ns` on the packets' clock.
  [[nodiscard]] bool poll(int64_t now_ns, Scan& scan);
  // A rotation is in progress (in the caller's scan), or packets or columns wait for the next.
  bool in_progress() const {
    return open_ || pending_slot_ >= 0 || window_size_ > 0 || closing_ || stashed_;
  }

  const BatcherStats& stats() const { return stats_; }
  // The sequence number the next rotation gets; a batcher that replaces another (a model change)
  // goes on from it, so that rotation numbers never repeat.
  uint64_t next_sequence() const { return sequence_; }
  void continue_sequence(uint64_t next) { sequence_ = next; }
  // Columns a scan needs for one rotation at 300 rpm (the slowest), with margin.
  static int column_capacity(const ModelSpec& spec);

 private:
  // A packet held back: its columns, pointing at its own copy of the bytes.
  struct Held {
    PacketColumns columns;
    std::array<uint8_t, kDataPacketSize> bytes;
  };
  // Columns decoded together into the scan: packets are held until this many are waiting, so
  // that each ring's run fills whole cache lines and its set-up is shared by more columns (32
  // measured 5-8% faster than 16 on every capture, 40 no faster; ColumnBatch holds 48).
  static constexpr int kBatchColumns = 32;
  static constexpr int kSlots = kReorderWindow + 3 + kBatchColumns;
  static constexpr int kHistory = 16;  // released packets remembered to recognise duplicates
  static constexpr int kGaps = 8;      // recent gaps counted as missing packets

  // What screening needs of a stream's newest packet.
  struct Ref {
    int64_t stamp_ns = 0;  // first column
    float first_azimuth_deg = 0, last_azimuth_deg = 0;
    float rate_deg_per_us = 0;  // measured inside the packet
  };
  static Ref ref_of(const PacketColumns& pk);
  enum class Verdict : uint8_t { kAccept, kAcceptHeadWasStray, kDuplicate, kTooLate, kSuspect };
  Verdict screen(const PacketColumns& pk) const;
  // Whether `pk` continues a stream whose newest packet is `ref` (time and azimuth agree).
  bool fits(const Ref& ref, const PacketColumns& pk) const;
  void hold(const PacketColumns& pk, Held& slot);
  void insert(const PacketColumns& pk);
  // Ends the stream in progress (the new stream's first packets wait in candidates_): what the
  // window holds goes into the rotation in progress, and a cut among it ends that rotation as
  // usual (true; the stream's tail is then ended by finish_close() on the next call). Otherwise
  // finish_close() at once. True when `scan` then holds a rotation.
  bool close_stream(Scan& scan, bool jump);
  // The rest of a closing stream into the rotation in progress, which is finished; then the new
  // stream's packets enter the window. True when `scan` then holds a rotation.
  bool finish_close(Scan& scan);
  // The rotation in progress finished (true when one was open) and the stream forgotten: the next
  // rotation does not start at a cut, and neither the last column nor the heads are known.
  bool end_stream(Scan& scan);
  bool adopt_new_stream(Scan& scan);
  // The held candidates of a new stream into the window, in order (their return mode taken).
  void insert_candidates();
  // add() without the deferred work of earlier calls.
  bool add_one(const PacketColumns& packet, Scan& scan);
  // Deferred work of earlier calls (a stream's tail, a packet that came meanwhile): true when it
  // ended a rotation.
  bool catch_up(Scan& scan);
  bool pump(Scan& scan);
  bool release_oldest(Scan& scan, bool may_end);
  void take_pending(Scan& scan);
  void forgive_gap(int64_t stamp_ns);
  // The newest packet taken was a stray one (the next fits the one before it): out it goes.
  void drop_stray_head();

  // The columns of `pk` from `first` on into `scan`. With `may_end`, a cut, jump or full scan
  // ends the rotation: true, and the columns from there on are kept (pending_*).
  bool run(const PacketColumns& pk, int first, Scan& scan, bool may_end);
  void begin(Scan& scan, int64_t stamp_ns);
  void finish(Scan& scan, bool ends_at_cut);
  bool crossed_cut(double from_deg, double to_deg) const;
  // Column bookkeeping; consecutive columns are decoded into the scan as one run, runs are
  // batched (write_batch() decodes them).
  void add_column(const PacketColumns& packet, int column, int64_t stamp_ns, Scan& scan);
  void queue_run(Scan& scan);
  void write_batch(Scan& scan);
  // After a held packet's columns were taken: its slot is free unless the batch still reads it.
  void done_with(int slot);

  const ModelSpec& spec_;
  ReturnMode mode_;
  BatcherOptions options_;
  bool open_ = false;  // the caller's scan holds a rotation in progress

  // Held packets: the reorder window (slot indices sorted by time, oldest first), the packet
  // whose columns after a cut wait for the next scan, and the candidates of a new stream.
  std::unique_ptr<std::array<Held, kSlots>> slots_;
  std::array<int, kSlots> window_{};
  int window_size_ = 0;
  std::array<bool, kSlots> busy_{};
  int pending_slot_ = -1;
  int pending_column_ = 0;
  uint32_t pending_missing_ = 0;
  bool pending_evaluated_ = false;
  // The candidates of a new stream, then one more: a packet that came while a call delivered the
  // closing stream's tail (stashed_), taken first on the next call.
  std::unique_ptr<std::array<Held, kNewStreamPackets + 1>> candidates_;
  int candidate_count_ = 0;
  bool closing_ = false, closing_jump_ = false;  // a stream's tail waits for the next call
  bool stashed_ = false;
  // The stream's newest packet taken (for screening).
  bool have_head_ = false, have_previous_head_ = false;
  Ref head_{}, previous_head_{};
  std::array<int64_t, kHistory> released_stamp_{};
  std::array<float, kHistory> released_azimuth_{};
  int released_count_ = 0;
  struct Gap {
    int64_t from_ns = 0, to_ns = 0;
    uint32_t missing = 0;
  };
  std::array<Gap, kGaps> gaps_{};
  int gap_next_ = 0;

  // The run of columns of the packet being written that waits to be decoded into the scan.
  const PacketColumns* packet_ = nullptr;
  int packet_slot_ = -1;  // its slot
  // Runs waiting to be decoded into the scan, from batch_column_ on, and the slots they read.
  ColumnBatch batch_;
  const Decoder* decoder_ = nullptr;  // the batch's
  int batch_column_ = 0;
  std::array<int, kSlots> batch_slots_{};
  int batch_slot_count_ = 0;
  int run_columns_ = 0, run_packet_column_ = 0, run_scan_column_ = 0;
  double run_time_offset_s_ = 0;
  BatcherStats stats_{};
  uint64_t sequence_ = 0;
  bool have_last_ = false;
  double last_column_azimuth_ = 0;
  int64_t last_column_stamp_ns_ = 0;
  int64_t last_packet_stamp_ns_ = 0;
  bool next_starts_at_cut_ = false;
  bool overflowed_ = false;
  // The last normal step (its rate, step / dt, is the rotation rate: 600 rpm at first).
  double last_rate_step_deg_ = 600.0 * 360.0 / 60e6, last_rate_dt_us_ = 1.0;
  double rate_steps_deg_ = 0, rate_time_us_ = 0;  // for the rotation's measured rpm
};

}  // namespace lidartag::velodyne
