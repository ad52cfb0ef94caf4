#include "lidartag/driver/scan_buffer.hpp"

#include <cstddef>

namespace lidartag::velodyne {

IndexQueue::IndexQueue(size_t capacity) {
  size_t n = 2;
  while (n < capacity) n *= 2;
  cells_ = std::make_unique<Cell[]>(n);
  mask_ = n - 1;
  for (size_t i = 0; i < n; ++i) cells_[i].sequence.store(i, std::memory_order_relaxed);
}

bool IndexQueue::push(uint32_t value) {
  size_t pos = enqueue_.load(std::memory_order_relaxed);
  for (;;) {
    Cell& cell = cells_[pos & mask_];
    const size_t seq = cell.sequence.load(std::memory_order_acquire);
    const auto diff = static_cast<std::ptrdiff_t>(seq) - static_cast<std::ptrdiff_t>(pos);
    if (diff == 0) {
      if (enqueue_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) {
        cell.value = value;
        cell.sequence.store(pos + 1, std::memory_order_release);
        return true;
      }
    } else if (diff < 0) {
      return false;  // full
    } else {
      pos = enqueue_.load(std::memory_order_relaxed);
    }
  }
}

bool IndexQueue::pop(uint32_t& value) {
  size_t pos = dequeue_.load(std::memory_order_relaxed);
  for (;;) {
    Cell& cell = cells_[pos & mask_];
    const size_t seq = cell.sequence.load(std::memory_order_acquire);
    const auto diff = static_cast<std::ptrdiff_t>(seq) - static_cast<std::ptrdiff_t>(pos + 1);
    if (diff == 0) {
      if (dequeue_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) {
        value = cell.value;
        cell.sequence.store(pos + mask_ + 1, std::memory_order_release);
        return true;
      }
    } else if (diff < 0) {
      return false;  // empty
    } else {
      pos = dequeue_.load(std::memory_order_relaxed);
    }
  }
}

// The queues hold at most half their capacity, so a push fails only for the instant another
// thread is finishing a pop of the same cell; retrying never loses an index.
void ScanBuffer::push_index(IndexQueue& queue, uint32_t index) {
  while (!queue.push(index)) {
  }
}

ScanBuffer::ScanBuffer(size_t depth, size_t consumers, int rings, int returns, int column_capacity)
    // The producer holds one scan being filled, each consumer one, and `depth` wait in between.
    // Twice the scans: a push can only find its cell busy while a pop of the cell one lap
    // earlier is still completing (see push_index).
    : free_(2 * (depth + consumers + 1)), ready_(2 * (depth + consumers + 1)) {
  const size_t total = depth + consumers + 1;
  scans_.reserve(total);
  for (size_t i = 0; i < total; ++i) {
    scans_.push_back(std::make_unique<Scan>());
    scans_.back()->reserve(rings, returns, column_capacity);
    push_index(free_, static_cast<uint32_t>(i));
  }
  depth_ = depth;
}

uint32_t ScanBuffer::index_of(const Scan* scan) const {
  for (size_t i = 0; i < scans_.size(); ++i)
    if (scans_[i].get() == scan) return static_cast<uint32_t>(i);
  return static_cast<uint32_t>(scans_.size());
}

Scan* ScanBuffer::acquire() {
  for (;;) {
    // Read before the pops: a release that ended before this load is visible to them.
    const int releasing = releasing_.load(std::memory_order_acquire);
    uint32_t i;
    if (free_.pop(i)) return scans_[i].get();
    // Consumers fell behind: recycle the oldest rotation still waiting.
    if (ready_.pop(i)) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return scans_[i].get();
    }
    // A queue cell whose push is half done hides it and every later cell from pop(). With a
    // consumer's release in that state the scan is free but not yet visible: wait for the push
    // (a few instructions) rather than drop a rotation. Seen under ThreadSanitizer, where a
    // preempted release made thousands of acquires in a row fail.
    if (releasing == 0) return nullptr;  // every scan is held by a consumer: the caller drops
  }
}

void ScanBuffer::publish(Scan* scan) {
  const uint32_t i = index_of(scan);
  if (i >= scans_.size()) return;
  // Keep at most `depth` rotations waiting: older ones are recycled first.
  while (ready_count() >= depth_) {
    uint32_t old;
    if (!ready_.pop(old)) break;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    push_index(free_, old);
  }
  push_index(ready_, i);
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
  if (i >= scans_.size()) return;
  releasing_.fetch_add(1, std::memory_order_acq_rel);
  push_index(free_, i);
  releasing_.fetch_sub(1, std::memory_order_release);
}

size_t ScanBuffer::ready_count() const {
  const uint64_t in = published_.load(std::memory_order_acquire);
  const uint64_t out =
      popped_.load(std::memory_order_acquire) + dropped_.load(std::memory_order_acquire);
  return in > out ? static_cast<size_t>(in - out) : 0;
}

}  // namespace lidartag::velodyne
