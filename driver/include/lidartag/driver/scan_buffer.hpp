// Lock-free, bounded, preallocated hand-over of rotations from the receiving thread to consumers.
// The producer never blocks: when consumers fall behind, the oldest queued rotation is recycled
// and counted as dropped.
#pragma once

#include <atomic>
#include <boost/lockfree/queue.hpp>
#include <cstdint>
#include <memory>
#include <vector>

#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/scan_batcher.hpp"

namespace lidartag::velodyne {

class ScanBuffer final : public ScanSink {
 public:
  // `depth` rotations may wait for consumers; each of up to `consumers` threads holds at most one
  // scan at a time (between pop and release). Every scan is reserved here, once.
  ScanBuffer(size_t depth, size_t consumers, int rings, int returns, int column_capacity);

  // Producer side (one thread).
  Scan* acquire() override;
  void publish(Scan* scan) override;

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
  boost::lockfree::queue<uint32_t, boost::lockfree::fixed_sized<true>> free_;
  boost::lockfree::queue<uint32_t, boost::lockfree::fixed_sized<true>> ready_;
  std::atomic<uint64_t> published_{0}, popped_{0}, dropped_{0};
  size_t depth_ = 0;
  uint32_t index_of(const Scan* scan) const;
};

}  // namespace lidartag::velodyne
