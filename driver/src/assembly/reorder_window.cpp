#include "lidartag/driver/assembly/reorder_window.hpp"

#include <algorithm>
#include <new>

#include "lidartag/driver/angles.hpp"

namespace lidartag::driver {

namespace {

// A held packet's bytes start at kMaxObjectBytes (a multiple of any alignment), and the next
// packet's object after them, rounded up to keep it aligned.
constexpr size_t kAlign = alignof(std::max_align_t);
static_assert(ColumnPacket::kMaxObjectBytes % kAlign == 0);

}  // namespace

size_t HeldPacket::storage_bytes(size_t max_payload_bytes) {
  return ColumnPacket::kMaxObjectBytes + (max_payload_bytes + kAlign - 1) / kAlign * kAlign;
}

HeldPacket::HeldPacket(std::byte* storage, size_t max_payload_bytes)
    : object_(storage, ColumnPacket::kMaxObjectBytes),
      packet_(new (storage) ColumnPacket{}),
      bytes_(reinterpret_cast<uint8_t*>(storage + ColumnPacket::kMaxObjectBytes)),
      capacity_(max_payload_bytes) {}

HeldPackets::HeldPackets(int count, size_t max_payload_bytes) {
  const size_t stride = HeldPacket::storage_bytes(max_payload_bytes);
  storage_.resize(static_cast<size_t>(count) * stride);
  for (int i = 0; i < count; ++i)
    packets_.emplace_back(storage_.data() + static_cast<size_t>(i) * stride, max_payload_bytes);
}

void HeldPacket::hold(const ColumnPacket& packet) {
  // The decoder copies its own type (what it later reads to decode the points); a packet without
  // one is only ever counted, never decoded: its header is enough.
  packet_ = packet.decoder != nullptr ? packet.decoder->copy_packet(packet, object_)
                                      : new (object_.data()) ColumnPacket(packet);
  const size_t n = std::min(packet.payload_size, capacity_);
  if (packet.payload != nullptr) std::copy_n(packet.payload, n, bytes_);
  packet_->payload = bytes_;
  packet_->payload_size = n;
}

int64_t last_stamp(const ColumnPacket& packet) {
  const auto last = static_cast<size_t>(std::max(packet.columns - 1, 0));
  return packet.stamp_ns + round_half_away(packet.column_time_us[last] * 1e3);
}

ReorderWindow::ReorderWindow(size_t max_payload_bytes) : slots_(kSlots, max_payload_bytes) {}

bool ReorderWindow::insert(const ColumnPacket& packet, bool& reordered) {
  int slot = 0;
  while (slot < kSlots && taken_[static_cast<size_t>(slot)]) ++slot;
  if (slot == kSlots) return false;
  taken_[static_cast<size_t>(slot)] = true;
  slots_[slot].hold(packet);
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
    const ColumnPacket& h = oldest(i);
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

}  // namespace lidartag::driver
