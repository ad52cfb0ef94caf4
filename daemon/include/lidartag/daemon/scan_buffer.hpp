// The hand-over of rotations from the receiving thread to the detection pipeline: a fixed set of
// slots that the receiver assembles in place, the pipeline takes in order, detects, publishes and
// releases. Bounded and preallocated; lock-free (two bounded index queues). The pipeline never
// waits here (it is told by the receiver when a rotation is ready); a replay's receiver waiting for
// a free slot sleeps on a C++20 atomic wait, woken by release(): no polling.
//
//   receiver: acquire() -> CaptureReader::read(slot->scan) -> publish()   (FIFO of waiting slots)
//   pipeline: try_take() -> detect -> publish in order -> release()
//
// A template over the slot (the daemon's is Rotation), so that the ThreadSanitizer test builds it
// without the detector.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

namespace lidartag::daemon {

// Bounded multi-producer multi-consumer queue of indices (D. Vyukov's array queue: one sequence
// number per cell, acquire/release on it orders the value). Written here rather than taken from
// boost::lockfree, whose freelist ThreadSanitizer reports as racy: this one it can verify.
class IndexQueue {
 public:
  explicit IndexQueue(size_t capacity);
  bool push(uint32_t value);  // false when full
  bool pop(uint32_t& value);  // false when empty
  // Retries a push that meets a pop of the same cell one lap earlier still completing; the
  // queues below are twice their contents, so it never finds the queue really full.
  void push_retrying(uint32_t value);

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

// What the receiver does when every slot is taken (the detector fell behind).
enum class Overflow : uint8_t {
  kDropOldest,  // live sources: never wait; the oldest waiting rotation is recycled and counted
  kWait,        // replays: wait for the pipeline to release a slot (back-pressure, no loss)
};

template <class Slot>
class ScanBuffer {
 public:
  // At most `depth` rotations wait for the pipeline, which holds at most `in_pipeline` between
  // try_take() and release() (its tokens); the receiver fills one more. The slots are created here
  // (the daemon's scans start empty: the batcher sizes each when it is first filled).
  ScanBuffer(size_t depth, size_t in_pipeline, Overflow overflow);

  // ---- The receiving thread. ----
  // A slot to assemble the next rotation in: a free one, else (kDropOldest, or after
  // stop_waiting()) the oldest waiting rotation, whose loss `dropped` reports; kWait sleeps until
  // the pipeline releases one. Take it before publishing the one just finished, so that at most
  // `depth` ever wait.
  Slot* acquire(bool& dropped);
  // A finished rotation to the pipeline (FIFO: rotation order).
  void publish(Slot* slot);
  // Nothing more comes (drained() once the waiting rotations are taken).
  void close();
  // The daemon stops: a kWait acquire() waiting now or later drops the oldest instead.
  void stop_waiting();

  // ---- The pipeline's first stage (one thread at a time). ----
  // The oldest waiting rotation, or nullptr when none waits.
  Slot* try_take();
  // Closed, and every rotation published was taken or dropped.
  bool drained() const;

  // ---- The pipeline's last stage (one thread at a time): the slot is free again. ----
  void release(Slot* slot);

  size_t waiting() const;  // published, neither taken nor dropped (exact when both sides rest)
  size_t depth() const { return depth_; }
  size_t slots() const { return slots_.size(); }
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  uint32_t index_of(const Slot* slot) const;

  std::vector<std::unique_ptr<Slot>> slots_;
  IndexQueue free_, ready_;
  size_t depth_;
  Overflow overflow_;
  std::atomic<bool> closed_{false}, stop_waiting_{false};
  // Bumped after every release and stop_waiting: what a waiting acquire() sleeps on (32 bits: a
  // futex word).
  std::atomic<uint32_t> released_epoch_{0};
  std::atomic<uint64_t> published_{0}, taken_{0}, dropped_{0};
};

// ---- Implementation ----

template <class Slot>
ScanBuffer<Slot>::ScanBuffer(size_t depth, size_t in_pipeline, Overflow overflow)
    : free_(2 * (depth + in_pipeline + 1)),
      ready_(2 * (depth + in_pipeline + 1)),
      depth_(depth),
      overflow_(overflow) {
  const size_t total = depth + in_pipeline + 1;
  slots_.reserve(total);
  for (size_t i = 0; i < total; ++i) {
    slots_.push_back(std::make_unique<Slot>());
    free_.push_retrying(static_cast<uint32_t>(i));
  }
}

template <class Slot>
uint32_t ScanBuffer<Slot>::index_of(const Slot* slot) const {
  for (size_t i = 0; i < slots_.size(); ++i) {
    if (slots_[i].get() == slot) return static_cast<uint32_t>(i);
  }
  return static_cast<uint32_t>(slots_.size());
}

template <class Slot>
Slot* ScanBuffer<Slot>::acquire(bool& dropped) {
  dropped = false;
  for (;;) {
    // Read before the pops: a release that ends after this load changes it, so the wait below
    // returns at once instead of missing it.
    const uint32_t seen = released_epoch_.load(std::memory_order_acquire);
    uint32_t i = 0;
    if (free_.pop(i)) return slots_[i].get();
    if (overflow_ == Overflow::kDropOldest || stop_waiting_.load(std::memory_order_acquire)) {
      if (ready_.pop(i)) {
        dropped_.fetch_add(1, std::memory_order_release);
        dropped = true;
        return slots_[i].get();
      }
    }
    // kWait with every slot in the pipeline; or, when dropping, a release half done (its slot is
    // free but not yet visible): sleep until the pipeline releases one.
    released_epoch_.wait(seen, std::memory_order_acquire);
  }
}

template <class Slot>
void ScanBuffer<Slot>::publish(Slot* slot) {
  const uint32_t i = index_of(slot);
  if (i >= slots_.size()) return;
  published_.fetch_add(1, std::memory_order_release);
  ready_.push_retrying(i);
}

template <class Slot>
void ScanBuffer<Slot>::close() {
  closed_.store(true, std::memory_order_release);
}

template <class Slot>
void ScanBuffer<Slot>::stop_waiting() {
  stop_waiting_.store(true, std::memory_order_release);
  released_epoch_.fetch_add(1, std::memory_order_release);
  released_epoch_.notify_all();
}

template <class Slot>
Slot* ScanBuffer<Slot>::try_take() {
  uint32_t i = 0;
  if (!ready_.pop(i)) return nullptr;
  taken_.fetch_add(1, std::memory_order_release);
  return slots_[i].get();
}

template <class Slot>
bool ScanBuffer<Slot>::drained() const {
  // close() follows the receiver's last publish and drop: the counts read after it are final.
  if (!closed_.load(std::memory_order_acquire)) return false;
  return published_.load(std::memory_order_acquire) ==
         taken_.load(std::memory_order_acquire) + dropped_.load(std::memory_order_acquire);
}

template <class Slot>
void ScanBuffer<Slot>::release(Slot* slot) {
  const uint32_t i = index_of(slot);
  if (i >= slots_.size()) return;
  free_.push_retrying(i);
  released_epoch_.fetch_add(1, std::memory_order_release);
  released_epoch_.notify_one();
}

template <class Slot>
size_t ScanBuffer<Slot>::waiting() const {
  const uint64_t in = published_.load(std::memory_order_acquire);
  const uint64_t out =
      taken_.load(std::memory_order_acquire) + dropped_.load(std::memory_order_acquire);
  return in > out ? static_cast<size_t>(in - out) : 0;
}

}  // namespace lidartag::daemon
