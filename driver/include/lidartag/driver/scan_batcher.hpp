// Parsed packets of any vendor -> whole rotations, cut at the column (firing) level where the
// vendor's delimiter says (a configurable azimuth, or a change of frame id).
// A small functor: the caller owns the scans and passes the one to fill with every packet; the
// batcher assembles straight into it (no second copy). Design notes: docs/scan-assembly.md.
// Its parts, each with one job (driver/include/lidartag/driver/assembly/): StreamScreen (which
// packets belong to the stream), ReorderWindow (late packets put in place), RotationAssembler
// (columns into rotations, where they end) and ColumnWriter (points decoded into the scan). This
// class joins them and keeps the rule that one call delivers at most one rotation.
#pragma once

#include <cstdint>
#include <memory>

#include "lidartag/driver/assembly/batcher_options.hpp"
#include "lidartag/driver/assembly/reorder_window.hpp"
#include "lidartag/driver/assembly/rotation_assembler.hpp"
#include "lidartag/driver/assembly/stream_screen.hpp"
#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::driver {

class ScanBatcher {
 public:
  // Packets held back to put reordered ones in place: a rotation is delivered this many packet
  // periods after its last packet (VLP-16: 5.3 ms, VLS-128: 0.7 ms).
  static constexpr int kReorderWindow = ReorderWindow::kDepth;
  // Consecutive packets that agree with each other but not with the stream, with no packet of
  // the stream in between, that make a new stream (restart, clock jump, replay loop).
  static constexpr int kNewStreamPackets = StreamScreen::kNewStreamPackets;

  // `layout`: the vendor's description of the sensor (velodyne::sensor_layout()); `return_mode`
  // and `returns`: of the packets expected first (ColumnPacket).
  ScanBatcher(const SensorLayout& layout, uint8_t return_mode, int returns, BatcherOptions options);
  ~ScanBatcher();
  ScanBatcher(const ScanBatcher&) = delete;
  ScanBatcher& operator=(const ScanBatcher&) = delete;

  // Adds one packet (parsed by a vendor's decoder: its columns are written straight into the scan
  // by that decoder, which must outlive this batcher's use of it). Returns true when
  // `scan` holds a finished rotation (complete or not: Scan::complete); columns after the cut are
  // kept and go first into the next scan passed in, which must then be another one (or this one,
  // once the caller is done with it). While it returns false, pass the same scan again: it holds
  // the rotation in progress. A call ends at most one rotation. A scan whose shape (rings,
  // returns) does not fit is reserved for the model when its rotation begins (first use,
  // return-mode change): a scan may start empty. Never throws, never allocates.
  [[nodiscard]] bool add(const ColumnPacket& packet, Scan& scan);
  // The stream ended: delivers what is held back and the rotation in progress (incomplete), one
  // rotation per call: call again while it returns true.
  [[nodiscard]] bool flush(Scan& scan);
  // No packet came for `silent_s` seconds (host time): after ReorderWindow::kReleaseAfter_s no
  // reordered packet is on its way and the held ones go into the rotation, which goes on; after
  // flush_timeout_s the source fell silent and the rotation in progress is delivered (flush()).
  // True when that ended a rotation (call again: one per call).
  [[nodiscard]] bool idle(double silent_s, Scan& scan);
  // A rotation is in progress (in the caller's scan), or packets or columns wait for the next.
  bool in_progress() const {
    return assembler_.open() || pending_slot_ >= 0 || window_.size() > 0 || closing_ || stashed_;
  }

  const BatcherStats& stats() const { return stats_; }
  // The sequence number the next rotation gets; a batcher that replaces another (a model change)
  // goes on from it, so that rotation numbers never repeat.
  uint64_t next_sequence() const { return assembler_.next_sequence(); }
  void continue_sequence(uint64_t next) { assembler_.continue_sequence(next); }
  // Columns a scan needs for one rotation at 300 rpm (the slowest), with margin.
  static int column_capacity(const SensorLayout& layout) {
    return RotationAssembler::column_capacity(layout);
  }

 private:
  // The held packets go into the rotation, which goes on; true when that ended it.
  bool release_held(Scan& scan);
  // add() without the deferred work of earlier calls.
  bool add_one(const ColumnPacket& packet, Scan& scan);
  // Deferred work of earlier calls (a stream's tail, a packet that came meanwhile): true when it
  // ended a rotation.
  bool catch_up(Scan& scan);
  void take(const ColumnPacket& packet);  // into the window
  bool pump(Scan& scan);                  // the window down to its depth
  bool release_oldest(Scan& scan, bool may_end);
  void take_pending(Scan& scan);
  void done_with(int slot);
  // Ends the stream in progress (the new stream's first packets wait among the candidates): what
  // the window holds goes into the rotation in progress, and a cut among it ends that rotation as
  // usual (true; the stream's tail is then ended by finish_close() on the next call). Otherwise
  // finish_close() at once. True when `scan` then holds a rotation.
  bool close_stream(Scan& scan, bool jump);
  // The rest of a closing stream into the rotation in progress, which is finished; then the new
  // stream's packets enter the window. True when `scan` then holds a rotation.
  bool finish_close(Scan& scan);
  bool end_stream(Scan& scan);
  bool adopt_new_stream(Scan& scan);
  // The candidates of a new stream into the window, in order (their return mode taken).
  void insert_candidates();

  SensorLayout layout_;  // the parts refer to it
  BatcherOptions options_;
  BatcherStats stats_{};
  ReorderWindow window_;
  StreamScreen screen_;
  RotationAssembler assembler_;
  int pending_slot_ = -1;  // the packet that ended a rotation: its other columns wait
  // A stream's tail waits for the next call (one rotation per call), and whether it ends at a
  // jump; a packet that came while a call delivered is stashed for the next call.
  bool closing_ = false, closing_jump_ = false;
  bool stashed_ = false;
  HeldPackets stash_;  // one packet
};

}  // namespace lidartag::driver
