// Decoded packets -> whole rotations, cut at a configurable azimuth at the column (firing) level.
// A small functor: the caller owns the scans and passes the one to fill with every packet; the
// batcher assembles straight into it (no second copy). Design notes: docs/scan-assembly.md.
#pragma once

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
  uint64_t rotations = 0;        // delivered
  uint64_t complete = 0;         // of which complete
  uint64_t incomplete = 0;       // partial first/last, loss, jumps, timeouts
  uint64_t missing_packets = 0;  // packets lost on the way (sequence gaps in the packet times)
  uint64_t azimuth_jumps = 0;
  uint64_t fov_gaps = 0;   // gaps recognised as a restricted field of view
  uint64_t overflows = 0;  // rotations cut because the scan was full
  uint64_t mode_changes = 0;
  // Packets dropped because their time is not after the last column's: duplicates and packets
  // overtaken by a later one. late_packets = duplicates + reordered once the two are told apart;
  // until then (duplicates and reordered zero) every late packet is counted here only.
  uint64_t late_packets = 0;
  uint64_t duplicates = 0;  // a packet seen before (same time): dropped (not counted yet: 0)
  uint64_t reordered = 0;   // a packet overtaken by a later one (not counted yet: 0)
  // Packets whose azimuth contradicts the stream's time and rotation rate (spoofed, or from
  // another sensor): dropped without cutting the rotation (not counted yet: 0).
  uint64_t inconsistent = 0;
};

class ScanBatcher {
 public:
  ScanBatcher(const ModelSpec& spec, ReturnMode mode, BatcherOptions options);
  ~ScanBatcher();
  ScanBatcher(const ScanBatcher&) = delete;
  ScanBatcher& operator=(const ScanBatcher&) = delete;

  // Adds one packet's columns to the rotation in progress in `scan`. Returns true when `scan`
  // holds a finished rotation (complete or not: Scan::complete); the packet's columns after the
  // cut are kept and go first into the next scan passed in, which must then be another one (or
  // this one, once the caller is done with it). While it returns false, pass the same scan again:
  // it holds the rotation in progress. A packet ends at most one rotation. A scan whose shape
  // (rings, returns) does not fit is reserved for the model when its rotation begins (first use,
  // return-mode change): a scan may start empty.
  [[nodiscard]] bool add(const DecodedPacket& packet, Scan& scan);
  // Finishes the rotation in progress (and the kept columns) in `scan` as incomplete (the stream
  // ended). False when there was nothing to deliver.
  [[nodiscard]] bool flush(Scan& scan);
  // Flushes when the last packet is older than flush_timeout_s; `now_ns` on the packets' clock.
  [[nodiscard]] bool poll(int64_t now_ns, Scan& scan);
  // A rotation is in progress (in the caller's scan) or columns wait for the next scan.
  bool in_progress() const { return open_ || pending_; }

  const BatcherStats& stats() const { return stats_; }
  // Columns a scan needs for one rotation at 300 rpm (the slowest), with margin.
  static int column_capacity(const ModelSpec& spec);

 private:
  // The columns of `pk` from `first` on into `scan`. With `may_end`, a cut, jump or full scan
  // ends the rotation: true, and the columns from there on are kept in pending_.
  bool run(const DecodedPacket& pk, int first, Scan& scan, bool may_end);
  void begin(Scan& scan, int64_t stamp_ns);
  void finish(Scan& scan, bool ends_at_cut);
  void keep(const DecodedPacket& pk, int column, uint32_t missing, bool evaluated);
  void take_pending(Scan& scan);
  bool crossed_cut(double from_deg, double to_deg) const;
  // Column bookkeeping; the points of consecutive columns are copied as one run per ring.
  void add_column(const DecodedPacket& packet, int column, int64_t stamp_ns, Scan& scan);
  void copy_run(Scan& scan);

  const ModelSpec& spec_;
  ReturnMode mode_;
  BatcherOptions options_;
  bool open_ = false;  // the caller's scan holds a rotation in progress
  // Columns of a packet that ended a rotation, for the next scan: a copy of the packet, the first
  // column kept, its loss (a loss straddling the cut counts in both rotations) and whether that
  // column was already compared with the one before it.
  std::unique_ptr<DecodedPacket> stash_;
  bool pending_ = false;
  int pending_column_ = 0;
  uint32_t pending_missing_ = 0;
  bool pending_evaluated_ = false;
  // Columns of the packet being added that are waiting to be copied into the scan.
  const DecodedPacket* packet_ = nullptr;
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
  double last_rate_deg_per_us_ = 600.0 * 360.0 / 60e6;  // updated from every normal step
  double rate_steps_deg_ = 0, rate_time_us_ = 0;        // for the rotation's measured rpm
};

}  // namespace lidartag::velodyne
