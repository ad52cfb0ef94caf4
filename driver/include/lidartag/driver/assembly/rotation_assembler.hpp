// Released packets' columns into rotations (docs/scan-assembly.md, "Where a rotation ends"): each
// column is classified once against the one before it (the next in the rotation, packets lost,
// a field-of-view gap, the cut, a jump of the stream), and one function ends a rotation. The cut
// is the vendor's rotation delimiter (SensorLayout::delimiter): the cut azimuth, or a change of
// the packets' frame id.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "lidartag/driver/assembly/batcher_options.hpp"
#include "lidartag/driver/assembly/column_writer.hpp"
#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::driver {

class RotationAssembler {
 public:
  // `return_mode` and `returns`: of the packets expected first (ColumnPacket).
  RotationAssembler(const SensorLayout& layout, uint8_t return_mode, int returns,
                    const BatcherOptions& options, ReorderWindow& held, BatcherStats& stats);

  // The columns of `packet` (held in `slot`, -1: not held) into `scan`. With `may_end`, a cut, a
  // jump or a full scan ends the rotation: true, and the packet's columns from there on wait
  // (resume() takes them into the next scan). Without it, a rotation never ends here.
  bool add_packet(const ColumnPacket& packet, int slot, Scan& scan, bool may_end);
  // The columns of the packet that ended the last rotation, from where it ended, into the next.
  void resume(const ColumnPacket& packet, int slot, Scan& scan);
  // The stream ended: the rotation in progress is finished (true when one was open), and the
  // next one neither starts at the cut nor follows any column.
  bool end_stream(Scan& scan);
  // The rotation in progress is up to date in the scan (its batch written).
  void write_pending(Scan& scan) { writer_.write_batch(scan); }
  // A packet counted as lost arrived after all (too late to be put in place): not lost.
  void forgive_loss(int64_t stamp_ns);

  bool open() const { return open_; }
  bool reads(int slot) const { return writer_.reads(slot); }
  std::optional<int64_t> last_column_stamp() const {
    return have_last_ ? std::optional<int64_t>(last_column_stamp_ns_) : std::nullopt;
  }
  uint8_t mode() const { return mode_; }
  void set_mode(uint8_t return_mode, int returns) {
    mode_ = return_mode;
    returns_ = returns;
  }
  uint64_t next_sequence() const { return sequence_; }
  void continue_sequence(uint64_t next) { sequence_ = next; }
  // Columns a scan needs for one rotation at 300 rpm (the slowest), with margin.
  static int column_capacity(const SensorLayout& layout);

 private:
  // What a column is, against the one before it.
  struct Step {
    bool cut = false;      // the rotation delimiter lies between them
    bool jump = false;     // a discontinuity of the stream
    uint32_t missing = 0;  // packets lost between them
  };
  static constexpr int kGaps = 8;  // recent gaps counted as missing packets

  bool run(const ColumnPacket& packet, int slot, int first, Scan& scan, bool may_end);
  Step classify(double azimuth_deg, int64_t stamp_ns, int per_packet);
  // kCutAzimuth: the cut azimuth lies in the arc (from, to] travelled clockwise.
  bool crossed_cut(double from_deg, double to_deg) const;
  // kFrameId: the frame of the column after the last one is that one (0), the next (1), a later
  // one (the frames between were lost: how many ahead) or an earlier one (-1: the stream jumped).
  int frame_step() const;
  void begin(Scan& scan, int64_t stamp_ns);
  void finish(Scan& scan, bool ends_at_cut);
  // Ends the rotation before column `c` (at `azimuth_deg`, `stamp_ns`); `carried_missing` is
  // counted in the next rotation too (a loss that straddles the cut).
  void end_before(Scan& scan, int c, double azimuth_deg, int64_t stamp_ns, uint32_t carried_missing,
                  bool ends_at_cut);
  void follow(double azimuth_deg, int64_t stamp_ns);

  const SensorLayout& layout_;
  uint8_t mode_;
  int returns_;
  bool frame_rule_;  // rotations end where the frame id changes (else at the cut azimuth)
  // The frame of the packet whose columns are being taken, and of the last column taken.
  bool has_frame_ = false;
  uint32_t frame_id_ = 0, last_frame_id_ = 0;
  BatcherOptions options_;
  BatcherStats& stats_;
  ColumnWriter writer_;
  bool open_ = false;  // the caller's scan holds a rotation in progress
  uint64_t sequence_ = 0;
  // The last column taken.
  bool have_last_ = false;
  double last_column_azimuth_ = 0;
  int64_t last_column_stamp_ns_ = 0;
  bool next_starts_at_cut_ = false;
  bool overflowed_ = false;
  // The column that ended the last rotation, already classified: where resume() starts.
  int pending_column_ = 0;
  uint32_t pending_missing_ = 0;
  bool pending_evaluated_ = false;
  // The last normal step (its rate, step / dt, is the rotation rate: 600 rpm at first).
  double last_rate_step_deg_ = 600.0 * 360.0 / 60e6, last_rate_dt_us_ = 1.0;
  double rate_steps_deg_ = 0, rate_time_us_ = 0;  // for the rotation's measured rpm
  struct Gap {
    int64_t from_ns = 0, to_ns = 0;
    uint32_t missing = 0;
  };
  std::array<Gap, kGaps> gaps_{};
  int gap_next_ = 0;
};

}  // namespace lidartag::driver
