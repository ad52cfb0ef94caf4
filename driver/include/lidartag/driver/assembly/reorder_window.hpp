// The packets a batcher holds back: the reorder window, sorted by time, and the slots that keep
// their bytes (which the column writer reads until its batch is written, and where a packet that
// ended a rotation waits with its remaining columns). Fixed storage, allocated once.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <span>
#include <vector>

#include "lidartag/driver/columns.hpp"
#include "lidartag/driver/reusing_allocator.hpp"

namespace lidartag::driver {

// A copy of a parsed packet (of its vendor's type, made by its decoder), pointing at this copy of
// its bytes, in storage of HeldPackets.
class HeldPacket {
 public:
  // The storage one held packet takes: the packet object (aligned for any type), then its bytes.
  static size_t storage_bytes(size_t max_payload_bytes);

  // Over `storage` (storage_bytes(max_payload_bytes), aligned for any type), which outlives it.
  HeldPacket(std::byte* storage, size_t max_payload_bytes);
  HeldPacket(const HeldPacket&) = delete;
  HeldPacket& operator=(const HeldPacket&) = delete;

  // Never allocates; the bytes beyond max_payload_bytes are not copied (cannot happen: a
  // vendor's packets are never larger than its SensorLayout says).
  void hold(const ColumnPacket& packet);
  const ColumnPacket& columns() const { return *packet_; }

 private:
  std::span<std::byte> object_;
  ColumnPacket* packet_;
  uint8_t* bytes_;
  size_t capacity_;
};

// Storage for `count` held packets, allocated once, in one block: neither zero-filled (a packet's
// bytes are written before they are read) nor given back to the system when freed (the next
// batcher of the thread reuses it: ReusingAllocator), so that a reader opened after another
// faults in no new pages for it.
class HeldPackets {
 public:
  HeldPackets(int count, size_t max_payload_bytes);
  HeldPacket& operator[](int i) { return packets_[static_cast<size_t>(i)]; }
  const HeldPacket& operator[](int i) const { return packets_[static_cast<size_t>(i)]; }

 private:
  std::vector<std::byte, ReusingAllocator<std::byte>> storage_;
  std::deque<HeldPacket> packets_;  // not movable: each points into storage_
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

  explicit ReorderWindow(size_t max_payload_bytes);

  int size() const { return size_; }
  const ColumnPacket& oldest(int i) const { return packet(order_[static_cast<size_t>(i)]); }
  const ColumnPacket& packet(int slot) const { return slots_[slot].columns(); }
  // Puts a copy of `packet` in place by time. False when no slot is free (cannot happen: the
  // batcher keeps the window at its depth); else `reordered` says whether it went before a
  // packet that arrived earlier.
  bool insert(const ColumnPacket& packet, bool& reordered);
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
  HeldPackets slots_;
  std::array<int, kSlots> order_{};        // slots of the window, oldest first
  std::array<int64_t, kSlots> last_ns_{};  // per slot: its packet's last column's time
  int size_ = 0;
  std::array<bool, kSlots> taken_{};
};

// Time of a packet's last column.
int64_t last_stamp(const ColumnPacket& packet);

}  // namespace lidartag::driver
