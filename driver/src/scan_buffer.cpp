#include "lidartag/driver/scan_buffer.hpp"

namespace lidartag::velodyne {

ScanBuffer::ScanBuffer(size_t depth, size_t consumers, int rings, int returns, int column_capacity)
    // The producer holds one scan being filled, each consumer one, and `depth` wait in between.
    : free_(depth + consumers + 1), ready_(depth + consumers + 1) {
  const size_t total = depth + consumers + 1;
  scans_.reserve(total);
  for (size_t i = 0; i < total; ++i) {
    scans_.push_back(std::make_unique<Scan>());
    scans_.back()->reserve(rings, returns, column_capacity);
    free_.bounded_push(static_cast<uint32_t>(i));
  }
  depth_ = depth;
}

uint32_t ScanBuffer::index_of(const Scan* scan) const {
  for (size_t i = 0; i < scans_.size(); ++i)
    if (scans_[i].get() == scan) return static_cast<uint32_t>(i);
  return static_cast<uint32_t>(scans_.size());
}

Scan* ScanBuffer::acquire() {
  uint32_t i;
  if (free_.pop(i)) return scans_[i].get();
  // Consumers fell behind: recycle the oldest rotation still waiting.
  if (ready_.pop(i)) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return scans_[i].get();
  }
  return nullptr;  // every scan is held by a consumer: the caller drops this rotation
}

void ScanBuffer::publish(Scan* scan) {
  const uint32_t i = index_of(scan);
  if (i >= scans_.size()) return;
  // Keep at most `depth` rotations waiting: older ones are recycled first.
  while (ready_count() >= depth_) {
    uint32_t old;
    if (!ready_.pop(old)) break;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    free_.bounded_push(old);
  }
  ready_.bounded_push(i);
  published_.fetch_add(1, std::memory_order_relaxed);
}

Scan* ScanBuffer::pop() {
  uint32_t i;
  if (!ready_.pop(i)) return nullptr;
  popped_.fetch_add(1, std::memory_order_relaxed);
  return scans_[i].get();
}

void ScanBuffer::release(Scan* scan) {
  const uint32_t i = index_of(scan);
  if (i < scans_.size()) free_.bounded_push(i);
}

size_t ScanBuffer::ready_count() const {
  const uint64_t in = published_.load(std::memory_order_acquire);
  const uint64_t out =
      popped_.load(std::memory_order_acquire) + dropped_.load(std::memory_order_acquire);
  return in > out ? static_cast<size_t>(in - out) : 0;
}

}  // namespace lidartag::velodyne
