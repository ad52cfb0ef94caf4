#include "lidartag/driver/assembly/column_writer.hpp"

#include <algorithm>

namespace lidartag::driver {

void ColumnWriter::queue_run(Scan& s, bool open) {
  if (run_columns_ == 0 || !open || packet_ == nullptr) {
    run_columns_ = 0;
    return;
  }
  const ColumnPacket& pk = *packet_;
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

namespace {

// Cells of columns [column, column + n) that hold no return, in returns [from, scan.returns).
void clear_cells(Scan& s, int from, int column, int n) {
  for (int r = from; r < s.returns; ++r)
    for (int ring = 0; ring < s.rings; ++ring) {
      const auto dst = static_cast<std::ptrdiff_t>(s.at(r, ring, column));
      std::fill_n(s.range.begin() + dst, n, 0.0f);
      std::fill_n(s.return_type.begin() + dst, n, ReturnType::kNone);
    }
}

}  // namespace

void ColumnWriter::write_batch(Scan& s) {
  const int n = batch_.columns;
  if (n > 0 && decoder_ != nullptr && batch_.returns <= s.returns &&
      batch_column_ + n <= s.column_capacity) {
    // Storage the scan has not zeroed yet (Scan::reserve_lazily) is zeroed before its first
    // write, but for the cells the decoder writes whole.
    s.prepare_columns(batch_column_ + n, batch_column_, batch_.returns);
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
    clear_cells(s, batch_.returns, batch_column_, n);  // single-return packets, dual scan
  } else if (n > 0 && batch_column_ + n <= s.column_capacity) {
    // Columns the decoder cannot write here (dual-return packets in a single-return scan: a new
    // stream whose first packets mixed modes, counted in mode_changes) hold no return rather
    // than what the scan held before: a scan's storage is reused without being cleared.
    s.prepare_columns(batch_column_ + n);
    clear_cells(s, 0, batch_column_, n);
  }
  batch_.clear();
  // The held packets the batch read are free now, but the one being written.
  for (int i = 0; i < batch_slot_count_; ++i) {
    const int slot = batch_slots_[static_cast<size_t>(i)];
    if (slot != packet_slot_) held_.free(slot);
  }
  batch_slot_count_ = 0;
}

bool ColumnWriter::reads(int slot) const {
  for (int i = 0; i < batch_slot_count_; ++i)
    if (batch_slots_[static_cast<size_t>(i)] == slot) return true;
  return false;
}

}  // namespace lidartag::driver
