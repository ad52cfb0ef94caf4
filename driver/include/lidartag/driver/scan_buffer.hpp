// Lock-free, bounded, preallocated hand-over of rotations from the receiving thread to consumers.
// The producer never waits for a consumer (only for a release already under way to finish its
// push): when consumers fall behind, the oldest queued rotation is recycled and counted as dropped.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "lidartag/driver/scan.hpp"

namespace lidartag::velodyne {

// Bounded multi-producer multi-consumer queue of indices (D. Vyukov's array queue: one sequence
// number per cell, acquire/release on it orders the value). Written here rather than taken from
// boost::lockfree, whose freelist ThreadSanitizer reports as racy: this one it can verify.
class IndexQueue {
 public:
  explicit IndexQueue(size_t capacity);
  bool push(uint32_t value);  // false when full
  bool pop(uint32_t& value);  // false when empty

 private:
  struct Cell {
    std::atomic<size_t> sequence{0};
    uint32_t value = 0;
  };
  std::unique_ptr<Cell[]> cells_;
  size_t mask_;
  alignas(64) std::atomic<size_t> enqueue_{0};
  alignas(64) std::atomic<size_t> dequeue_{0};
};

class ScanBuffer final {
 public:
  // `depth` rotations may wait for consumers; each of up to `consumers` threads holds at most one
  // scan at a time (between pop and release). Every scan is reserved here, once.
  ScanBuffer(size_t depth, size_t consumers, int rings, int returns, int column_capacity);

  // Producer side (one thread). acquire() waits only for a consumer's release() that is half done
  // (a scan that is free but not yet visible); nullptr when every scan is really taken.
  Scan* acquire();
  void publish(Scan* scan);

  // Consumer side (any number of threads). pop() returns nullptr when nothing is ready.
  Scan* pop();
  void release(Scan* scan);

  uint64_t published() const { return published_.load(std::memory_order_relaxed); }
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  // Rotations waiting for a consumer (exact when the producer is quiet; for status reports).
  size_t ready_count() const;
  size_t depth() const { return depth_; }

 private:
  std::vector<std::unique_ptr<Scan>> scans_;
  IndexQueue free_;
  IndexQueue ready_;
  std::atomic<uint64_t> published_{0}, popped_{0}, dropped_{0};
  // Releases under way: their index is on its way into free_ and not yet visible to a pop.
  std::atomic<int> releasing_{0};
  size_t depth_ = 0;
  uint32_t index_of(const Scan* scan) const;
  static void push_index(IndexQueue& queue, uint32_t index);
};

}  // namespace lidartag::velodyne
