// Columns into the scan: consecutive columns of a packet make a run, runs that go to
// consecutive scan columns make a batch, and the decoder that parsed the packets writes each
// batch straight into the scan's ring-major storage (ColumnDecoder::write_batch, one virtual call
// per batch of about 32 columns): no copy of points.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "lidartag/driver/assembly/reorder_window.hpp"
#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::driver {

class ColumnWriter {
 public:
  // Columns decoded together: packets are held until this many are waiting, so that each ring's
  // run fills whole cache lines and its set-up is shared by more columns (32 measured 5-8 %
  // faster than 16 on every capture, 40 no faster; ColumnBatch holds 48).
  static constexpr int kBatchColumns = ReorderWindow::kBatchColumns;

  // The held packets a batch reads are freed in `held` once it is written.
  explicit ColumnWriter(ReorderWindow& held) : held_(held) {}

  // The packet whose columns come next, and its slot in the held packets (-1: not held).
  void start_packet(const ColumnPacket& packet, int slot) {
    packet_ = &packet;
    packet_slot_ = slot;
  }
  // Column `c` of the current packet, firing at `stamp_ns`, is the scan's next column (inline:
  // once per column).
  void add_column(int c, int64_t stamp_ns, Scan& scan) {
    const ColumnPacket& pk = *packet_;
    const int col = scan.columns++;
    const auto ucol = static_cast<size_t>(col);
    // The column's start from the scan's start.
    const double t0 = static_cast<double>(stamp_ns - scan.stamp_ns) * 1e-9;
    scan.column_azimuth_deg[ucol] = pk.column_azimuth_deg[static_cast<size_t>(c)];
    scan.column_time_s[ucol] = t0;
    if (col == 0) {
      ++scan.packets;
      if (pk.laser_of_ring != nullptr)
        std::copy_n(pk.laser_of_ring, std::min(scan.rings, pk.rings), scan.laser_id.begin());
    }
    if (c == 0 && col > 0) ++scan.packets;
    if (run_columns_ == 0) {
      run_packet_column_ = c;
      run_scan_column_ = col;
      // The packet's firing times are relative to its first column; the scan's to its own start.
      run_time_offset_s_ = t0 - pk.column_time_us[static_cast<size_t>(c)] * 1e-6;
    }
    ++run_columns_;
  }
  // The current run into the batch (`open`: a rotation is in progress to take it).
  void queue_run(Scan& scan, bool open);
  // The current packet is done with (its run queued; written at once when the packet is not
  // held: the batch reads the packet until it is written).
  void end_packet(Scan& scan, bool open) {
    queue_run(scan, open);
    if (packet_slot_ < 0) write_batch(scan);
    packet_ = nullptr;
    packet_slot_ = -1;
  }
  // Decodes the batch into the scan.
  void write_batch(Scan& scan);
  // The batch still reads this held packet (it is freed when the batch is written).
  bool reads(int slot) const;

 private:
  ReorderWindow& held_;
  const ColumnPacket* packet_ = nullptr;
  int packet_slot_ = -1;
  // The run of the current packet's columns waiting to join the batch.
  int run_columns_ = 0, run_packet_column_ = 0, run_scan_column_ = 0;
  double run_time_offset_s_ = 0;
  // Runs waiting to be decoded into the scan from scan column batch_column_ on, and the held
  // packets they read.
  ColumnBatch batch_;
  const ColumnDecoder* decoder_ = nullptr;
  int batch_column_ = 0;
  std::array<int, ReorderWindow::kSlots> batch_slots_{};
  int batch_slot_count_ = 0;
};

}  // namespace lidartag::driver
