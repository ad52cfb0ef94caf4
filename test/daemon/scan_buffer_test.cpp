// The hand-over of rotations: bounded, preallocated, in order; drop-oldest for live sources,
// back-pressure without loss for replays (the waiting receiver sleeps and is woken). Also built
// and run under ThreadSanitizer by scripts/run-tests.sh.
#include "lidartag/daemon/scan_buffer.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <set>
#include <thread>

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

// A slot as the daemon's Rotation is used here: a sequence number and a value written with it.
struct Slot {
  struct {
    uint64_t sequence = 0;
  } scan;
  int64_t assembled_ns = 0;
};
using Buffer = ScanBuffer<Slot>;
using Rotation = Slot;

TEST(ScanBuffer, DeliversInOrderAndRecyclesSlots) {
  Buffer buf(3, 1, Overflow::kDropOldest);
  EXPECT_EQ(buf.slots(), 5u);
  std::set<const Rotation*> seen;
  for (uint64_t i = 0; i < 10; ++i) {
    bool dropped = true;
    Rotation* r = buf.acquire(dropped);
    ASSERT_NE(r, nullptr);
    EXPECT_FALSE(dropped);
    seen.insert(r);
    r->scan.sequence = i;
    buf.publish(r);
    Rotation* got = buf.try_take();
    ASSERT_EQ(got, r);  // the same slot: filled once, never copied
    EXPECT_EQ(got->scan.sequence, i);
    buf.release(got);
  }
  EXPECT_LE(seen.size(), buf.slots());
  EXPECT_EQ(buf.waiting(), 0u);
  EXPECT_EQ(buf.dropped(), 0u);
}

TEST(ScanBuffer, LiveSourceDropsTheOldestWhenThePipelineFallsBehind) {
  Buffer buf(3, 1, Overflow::kDropOldest);
  Rotation* held = nullptr;
  bool dropped = false;
  Rotation* r = buf.acquire(dropped);
  int drops = 0;
  for (uint64_t i = 0; i < 8; ++i) {
    r->scan.sequence = i;
    Rotation* next = buf.acquire(dropped);  // before publishing: at most `depth` wait
    drops += dropped ? 1 : 0;
    ASSERT_NE(next, nullptr) << "the receiver always gets a slot";
    buf.publish(r);
    EXPECT_LE(buf.waiting(), 3u);
    if (i == 0) held = buf.try_take();  // the pipeline takes one and stalls
    r = next;
  }
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(held->scan.sequence, 0u);
  EXPECT_EQ(buf.waiting(), 3u);
  EXPECT_EQ(drops, 4);  // 1..4 dropped, 5..7 wait
  EXPECT_EQ(buf.dropped(), 4u);
  for (uint64_t want = 5; want < 8; ++want) {
    Rotation* got = buf.try_take();
    ASSERT_NE(got, nullptr);
    EXPECT_EQ(got->scan.sequence, want);
    buf.release(got);
  }
  buf.release(held);
}

TEST(ScanBuffer, ReplayWaitsForTheSlotThePipelineReleasesAndLosesNothing) {
  Buffer buf(1, 1, Overflow::kWait);
  bool dropped = false;
  Rotation* a = buf.acquire(dropped);
  Rotation* b = buf.acquire(dropped);
  Rotation* c = buf.acquire(dropped);  // the three slots: all taken now
  buf.publish(a);
  Rotation* in_pipeline = buf.try_take();
  buf.publish(b);
  std::atomic<bool> got{false};
  std::thread receiver([&] {
    bool d = true;
    Rotation* r = buf.acquire(d);  // sleeps: nothing free, nothing may be dropped
    EXPECT_EQ(r, in_pipeline);
    EXPECT_FALSE(d);
    got.store(true);
  });
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(got.load());
  buf.release(in_pipeline);  // wakes it
  receiver.join();
  EXPECT_TRUE(got.load());
  EXPECT_EQ(buf.dropped(), 0u);
  (void)c;
}

TEST(ScanBuffer, StopWaitingEndsTheReplaysWaitByDroppingTheOldest) {
  Buffer buf(1, 1, Overflow::kWait);
  bool dropped = false;
  Rotation* a = buf.acquire(dropped);
  Rotation* b = buf.acquire(dropped);
  (void)buf.acquire(dropped);
  buf.publish(a);
  (void)buf.try_take();  // held by a stuck pipeline
  buf.publish(b);
  std::thread receiver([&] {
    bool d = false;
    EXPECT_EQ(buf.acquire(d), b);
    EXPECT_TRUE(d);
  });
  std::this_thread::sleep_for(20ms);
  buf.stop_waiting();
  receiver.join();
  EXPECT_EQ(buf.dropped(), 1u);
}

TEST(ScanBuffer, DrainedOnceClosedAndEverythingTakenOrDropped) {
  ScanBuffer<Slot> buf(2, 1, Overflow::kDropOldest);
  EXPECT_EQ(buf.try_take(), nullptr);
  EXPECT_FALSE(buf.drained());
  bool dropped = false;
  Slot* a = buf.acquire(dropped);
  buf.publish(a);
  buf.close();
  EXPECT_FALSE(buf.drained());  // one still waits
  Slot* got = buf.try_take();
  EXPECT_EQ(got, a);
  EXPECT_TRUE(buf.drained());
  buf.release(got);
}

TEST(ScanBuffer, ConcurrentReceiverAndPipelineLoseNothingUncounted) {
  for (Overflow overflow : {Overflow::kDropOldest, Overflow::kWait}) {
    SCOPED_TRACE(overflow == Overflow::kWait ? "wait" : "drop oldest");
    constexpr uint64_t kRotations = 20000;
    Buffer buf(4, 2, overflow);
    std::atomic<uint64_t> consumed{0}, order_errors{0};
    // The pipeline: a serial first stage hands out in order; two "workers" release out of order.
    std::thread pipeline([&] {
      uint64_t last = 0;
      bool first = true;
      Rotation* pending = nullptr;
      for (;;) {
        Rotation* r = buf.try_take();
        if (r == nullptr) {
          if (buf.drained()) break;
          std::this_thread::yield();  // the daemon's pipeline is told instead (flow graph)
          continue;
        }
        if (!first && r->scan.sequence <= last) order_errors.fetch_add(1);
        if (r->assembled_ns != static_cast<int64_t>(r->scan.sequence)) order_errors.fetch_add(1);
        last = r->scan.sequence;
        first = false;
        consumed.fetch_add(1);
        if (pending != nullptr) {  // two in flight at most: release the older after the newer
          buf.release(r);
          buf.release(pending);
          pending = nullptr;
        } else {
          pending = r;
        }
      }
      if (pending != nullptr) buf.release(pending);
    });
    uint64_t drops = 0;
    bool dropped = false;
    Rotation* r = buf.acquire(dropped);
    for (uint64_t i = 0; i < kRotations; ++i) {
      r->scan.sequence = i;
      r->assembled_ns = static_cast<int64_t>(i);
      Rotation* next = buf.acquire(dropped);
      drops += dropped ? 1u : 0u;
      buf.publish(r);
      r = next;
    }
    buf.close();
    pipeline.join();
    EXPECT_EQ(order_errors.load(), 0u);
    EXPECT_EQ(drops, buf.dropped());
    EXPECT_EQ(consumed.load() + drops, kRotations);
    if (overflow == Overflow::kWait) {
      EXPECT_EQ(drops, 0u);
    }
  }
}

}  // namespace
}  // namespace lidartag::daemon
