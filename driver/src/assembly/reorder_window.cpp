#include "lidartag/driver/assembly/reorder_window.hpp"

#include <algorithm>

#include "../angles.hpp"

namespace lidartag::velodyne {

void HeldPacket::hold(const PacketColumns& packet) {
  columns = packet;
  if (packet.payload != nullptr) std::copy_n(packet.payload, kDataPacketSize, bytes.begin());
  columns.payload = bytes.data();
}

int64_t last_stamp(const PacketColumns& packet) {
  const auto last = static_cast<size_t>(std::max(packet.columns - 1, 0));
  return packet.stamp_ns + round_half_away(packet.column_time_us[last] * 1e3);
}

ReorderWindow::ReorderWindow() : slots_(std::make_unique<std::array<HeldPacket, kSlots>>()) {}

bool ReorderWindow::insert(const PacketColumns& packet, bool& reordered) {
  int slot = 0;
  while (slot < kSlots && taken_[static_cast<size_t>(slot)]) ++slot;
  if (slot == kSlots) return false;
  taken_[static_cast<size_t>(slot)] = true;
  (*slots_)[static_cast<size_t>(slot)].hold(packet);
  last_ns_[static_cast<size_t>(slot)] = last_stamp(packet);
  // Sorted by time, oldest first; a packet placed before a later one arrived out of order.
  int i = size_;
  while (i > 0 && oldest(i - 1).stamp_ns > packet.stamp_ns) {
    order_[static_cast<size_t>(i)] = order_[static_cast<size_t>(i - 1)];
    --i;
  }
  reordered = i < size_;
  order_[static_cast<size_t>(i)] = slot;
  ++size_;
  return true;
}

int ReorderWindow::pop_oldest() {
  const int slot = order_[0];
  std::copy(order_.begin() + 1, order_.begin() + size_, order_.begin());
  --size_;
  return slot;
}

void ReorderWindow::remove(int64_t stamp_ns) {
  for (int i = 0; i < size_; ++i) {
    const int slot = order_[static_cast<size_t>(i)];
    if (packet(slot).stamp_ns != stamp_ns) continue;
    std::copy(order_.begin() + i + 1, order_.begin() + size_, order_.begin() + i);
    --size_;
    free(slot);
    return;
  }
}

bool ReorderWindow::holds(int64_t stamp_ns, float azimuth_deg) const {
  for (int i = 0; i < size_; ++i) {
    const PacketColumns& h = oldest(i);
    if (h.stamp_ns == stamp_ns && h.column_azimuth_deg[0] == azimuth_deg) return true;
  }
  return false;
}

bool ReorderWindow::overlaps(int64_t first_ns, int64_t last_ns) const {
  for (int i = 0; i < size_; ++i) {
    const int slot = order_[static_cast<size_t>(i)];
    if (first_ns <= last_ns_[static_cast<size_t>(slot)] && packet(slot).stamp_ns <= last_ns)
      return true;
  }
  return false;
}

}  // namespace lidartag::velodyne
