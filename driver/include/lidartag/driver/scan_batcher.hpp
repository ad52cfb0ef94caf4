// Decoded packets -> whole rotations, cut at a configurable azimuth at the column (firing) level.
// Design notes: docs/scan-assembly.md.
#pragma once

#include <cstdint>

#include "lidartag/driver/decoder.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/sensor_model.hpp"

namespace lidartag::velodyne {

// Where finished rotations go and where empty ones come from (the ScanBuffer). Both calls come
// from the batcher's thread and must not block.
class ScanSink {
 public:
  virtual ~ScanSink() = default;
  virtual Scan* acquire() = 0;           // an empty scan, or nullptr if none can be had
  virtual void publish(Scan* scan) = 0;  // a finished rotation
};

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
  uint64_t rotations = 0;          // delivered
  uint64_t complete = 0;           // of which complete
  uint64_t incomplete = 0;         // partial first/last, loss, jumps, timeouts
  uint64_t dropped_no_buffer = 0;  // rotations lost because the sink had no free scan
  uint64_t missing_packets = 0;    // packets lost (timestamp gaps), all rotations
  uint64_t azimuth_jumps = 0;
  uint64_t fov_gaps = 0;   // gaps recognised as a restricted field of view
  uint64_t overflows = 0;  // rotations cut because the scan was full
  uint64_t mode_changes = 0;
  uint64_t late_packets = 0;  // duplicates and reordered packets, dropped
};

class ScanBatcher {
 public:
  ScanBatcher(const ModelSpec& spec, ReturnMode mode, BatcherOptions options, ScanSink& sink);

  // Adds one packet's columns; publishes 0, 1 or (on a tiny rotation) more rotations.
  void add(const DecodedPacket& packet);
  // Delivers the rotation in progress, if any, as incomplete (stream ended).
  void flush();
  // Flushes when the last packet is older than flush_timeout_s; `now_ns` on the packets' clock.
  void poll(int64_t now_ns);

  const BatcherStats& stats() const { return stats_; }
  // Columns a scan needs for one rotation at 300 rpm (the slowest), with margin.
  static int column_capacity(const ModelSpec& spec);

 private:
  void begin(double column_azimuth);
  void finish(bool ends_at_cut);
  bool crossed_cut(double from_deg, double to_deg) const;
  // Column bookkeeping; the points of consecutive columns are copied as one run per ring.
  void add_column(const DecodedPacket& packet, int column, int64_t stamp_ns);
  void copy_run();

  const ModelSpec& spec_;
  ReturnMode mode_;
  BatcherOptions options_;
  ScanSink& sink_;
  Scan* scan_ = nullptr;
  // Columns of the packet being added that are waiting to be copied into scan_.
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
  bool dropping_ = false;  // no scan could be had; skipping to the next cut
  double last_rate_deg_per_us_ = 600.0 * 360.0 / 60e6;  // updated from every normal step
  double rate_steps_deg_ = 0, rate_time_us_ = 0;        // for the rotation's measured rpm
};

}  // namespace lidartag::velodyne
