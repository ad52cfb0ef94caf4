// The packets a batcher holds back: the reorder window, sorted by time, and the slots that keep
// their bytes (which the column writer reads until its batch is written, and where a packet that
// ended a rotation waits with its remaining columns). Fixed storage, allocated once.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "lidartag/driver/decoder.hpp"
#include "lidartag/driver/packet.hpp"

namespace lidartag::velodyne {

// A packet's columns, pointing at this copy of its bytes.
struct HeldPacket {
  PacketColumns columns;
  std::array<uint8_t, kDataPacketSize> bytes;

  void hold(const PacketColumns& packet);
};

class ReorderWindow {
 public:
  // Packets held to put late ones in place: a rotation is delivered this many packet periods
  // after its last packet (VLP-16: 5.3 ms, VLS-128: 0.7 ms).
  static constexpr int kDepth = 4;
  // Columns the writer decodes together (ColumnWriter::kBatchColumns): the held packets its batch
  // may still read.
  static constexpr int kBatchColumns = 32;
  // The window, one more while it is over its depth, a waiting packet, the batch's packets.
  static constexpr int kSlots = kDepth + 3 + kBatchColumns;
  // A pause of the source this long (host time) means no reordered packet is on its way.
  static constexpr double kReleaseAfter_s = 0.005;

  ReorderWindow();

  int size() const { return size_; }
  const PacketColumns& oldest(int i) const { return packet(order_[static_cast<size_t>(i)]); }
  const PacketColumns& packet(int slot) const {
    return (*slots_)[static_cast<size_t>(slot)].columns;
  }
  // Puts a copy of `packet` in place by time. False when no slot is free (cannot happen: the
  // batcher keeps the window at its depth); else `reordered` says whether it went before a
  // packet that arrived earlier.
  bool insert(const PacketColumns& packet, bool& reordered);
  // The oldest packet's slot, out of the window; it stays taken until free().
  int pop_oldest();
  void free(int slot) { taken_[static_cast<size_t>(slot)] = false; }
  // Takes the packet of this time out of the window (a stray one that fitted by chance).
  void remove(int64_t stamp_ns);
  // A packet of this time and first azimuth is in the window.
  bool holds(int64_t stamp_ns, float azimuth_deg) const;
  // A packet in the window overlaps [first_ns, last_ns] in time.
  bool overlaps(int64_t first_ns, int64_t last_ns) const;

 private:
  std::unique_ptr<std::array<HeldPacket, kSlots>> slots_;
  std::array<int, kSlots> order_{};        // slots of the window, oldest first
  std::array<int64_t, kSlots> last_ns_{};  // per slot: its packet's last column's time
  int size_ = 0;
  std::array<bool, kSlots> taken_{};
};

// Time of a packet's last column.
int64_t last_stamp(const PacketColumns& packet);

}  // namespace lidartag::velodyne
