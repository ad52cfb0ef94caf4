// Options and counters of scan assembly (ScanBatcher and its parts).
#pragma once

#include <cstdint>

#include "lidartag/options/rules.hpp"

namespace lidartag::driver {

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

// The rule table of BatcherOptions (lidartag/options/rules.hpp): keys, rules, units.
template <class V>
void visit_batcher_options(V& v, BatcherOptions& o) {
  using namespace rules;
  v.field("cut_azimuth_deg", o.cut_azimuth_deg, half_open(0.0, 360.0), "deg");
  // At least 10 ms: many packet periods of every model (less blamed whole streams on spoofing).
  v.field("flush_timeout_s", o.flush_timeout_s, closed(0.01, 3600.0), "s");
  v.field("max_column_step_deg", o.max_column_step_deg, above(0.0), "deg");
}

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

}  // namespace lidartag::driver
