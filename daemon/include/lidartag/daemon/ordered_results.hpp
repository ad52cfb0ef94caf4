// The reorder stage: rotations are detected in parallel and finish in any order; the publisher
// gets them back in the order they were taken from the scan buffer (rotation order, since the
// buffer is FIFO). Bounded: a fixed set of slots, one per rotation between pop and publication;
// when they are all in use no rotation is taken, so the scan buffer (which drops the oldest)
// absorbs the backlog and nothing queues without bound. Never allocates after construction.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "lidartag/daemon/scan_copy.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::daemon {

// What the publisher needs of one processed rotation.
struct RotationResult {
  uint64_t sequence = 0;
  int64_t stamp_ns = 0;      // first firing, ns since the epoch
  int64_t end_stamp_ns = 0;  // last column's firing
  bool complete = false;
  int columns = 0;
  int points = 0;
  float rpm = 0;
  // Steady-clock times (ns): rotation assembled, taken by a worker, detection finished.
  int64_t assembled_ns = 0, taken_ns = 0, detected_ns = 0;
  detector::ScanResult detection;
  // Every k-th column's returns, when lcm.cloud_decimation = k > 0 (the scan itself goes back to
  // the buffer before publication).
  DecimatedCloud cloud;
};

class OrderedResults {
 public:
  struct Slot {
    RotationResult result;
    Scan* scan = nullptr;  // the rotation being detected (until complete())
    int detector = -1;     // index of the detector the worker uses
    bool done = false;
  };

  // `detectors` workers may hold a slot at once; `publish_queue` finished rotations may wait for
  // the publisher.
  OrderedResults(size_t detectors, size_t publish_queue);

  // Takes the next rotation from `pop` (a callable returning Scan* or nullptr) under the ordering
  // lock, so that taking order is rotation order, with a slot and a free detector. nullptr when
  // no slot or detector is free (nothing is popped then) or `pop` had nothing.
  template <class Pop>
  Slot* take(Pop&& pop, int64_t now_ns);

  // Detection of `slot` finished (any thread). Wakes the publisher when it is next in order.
  void complete(Slot* slot);

  // The next finished rotation in order, or nullptr after `wait` (publisher thread).
  Slot* next_ready(std::chrono::milliseconds wait);
  // Returns a published slot.
  void recycle(Slot* slot);

  bool has_free_slot() const;
  size_t in_use() const;  // slots between take() and recycle()
  // Steady-clock time when the oldest rotation still in detection was taken; 0 if none.
  int64_t oldest_in_detection_ns() const;
  size_t capacity() const { return slots_.size(); }

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::vector<Slot> slots_;
  std::vector<Slot*> free_slots_;
  std::vector<int> free_detectors_;
  std::vector<Slot*> order_;  // ring of taken slots, in taking order
  size_t head_ = 0, count_ = 0;
};

template <class Pop>
OrderedResults::Slot* OrderedResults::take(Pop&& pop, int64_t now_ns) {
  std::lock_guard lock(mutex_);
  if (free_slots_.empty() || free_detectors_.empty()) return nullptr;
  Scan* scan = pop();
  if (scan == nullptr) return nullptr;
  Slot* slot = free_slots_.back();
  free_slots_.pop_back();
  slot->detector = free_detectors_.back();
  free_detectors_.pop_back();
  slot->scan = scan;
  slot->done = false;
  slot->result.taken_ns = now_ns;
  order_[(head_ + count_) % order_.size()] = slot;
  ++count_;
  return slot;
}

}  // namespace lidartag::daemon
