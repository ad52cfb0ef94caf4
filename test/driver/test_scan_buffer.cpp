// The lock-free hand-over: bounded, preallocated, the producer never blocks, oldest dropped.
// Also built and run under ThreadSanitizer by .ci/run.
#include <gtest/gtest.h>

#include <atomic>
#include <set>
#include <thread>

#include "lidartag/driver/scan_buffer.hpp"

namespace lidartag::velodyne {
namespace {

TEST(ScanBuffer, DeliversInOrderAndRecyclesScans) {
  ScanBuffer buf(3, 1, 16, 1, 100);
  for (uint64_t i = 0; i < 10; ++i) {
    Scan* s = buf.acquire();
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->rings, 16);
    EXPECT_EQ(s->column_capacity, 100);
    s->sequence = i;
    buf.publish(s);
    Scan* got = buf.pop();
    ASSERT_NE(got, nullptr);
    EXPECT_EQ(got->sequence, i);
    buf.release(got);
  }
  EXPECT_EQ(buf.pop(), nullptr);
  EXPECT_EQ(buf.dropped(), 0u);
}

TEST(ScanBuffer, OldestIsDroppedWhenConsumersFallBehind) {
  ScanBuffer buf(3, 1, 16, 1, 10);
  Scan* held = nullptr;
  for (uint64_t i = 0; i < 8; ++i) {
    Scan* s = buf.acquire();
    ASSERT_NE(s, nullptr) << "the producer must always get a scan";
    s->sequence = i;
    buf.publish(s);
    if (i == 0) held = buf.pop();  // a consumer holds one scan and stalls
  }
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(held->sequence, 0u);
  EXPECT_EQ(buf.ready_count(), 3u);
  EXPECT_EQ(buf.dropped(), 4u);  // 1..4 dropped, 5..7 wait
  for (uint64_t want = 5; want < 8; ++want) {
    Scan* s = buf.pop();
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->sequence, want);
    buf.release(s);
  }
  buf.release(held);
}

TEST(ScanBuffer, ConcurrentProducerAndConsumersLoseNothingUncounted) {
  constexpr uint64_t kScans = 20000;
  ScanBuffer buf(4, 2, 4, 1, 8);
  std::atomic<bool> done{false};
  std::atomic<uint64_t> consumed{0};
  std::atomic<uint64_t> order_errors{0};
  auto consumer = [&] {
    uint64_t last = 0;
    bool first = true;
    while (true) {
      Scan* s = buf.pop();
      if (s == nullptr) {
        if (done.load(std::memory_order_acquire) && buf.ready_count() == 0) {
          s = buf.pop();
          if (s == nullptr) break;
        } else {
          std::this_thread::yield();
          continue;
        }
      }
      // Each consumer sees increasing sequence numbers; the content is intact.
      if (!first && s->sequence <= last) order_errors.fetch_add(1);
      if (s->x[0] != static_cast<float>(s->sequence % 1000)) order_errors.fetch_add(1);
      last = s->sequence;
      first = false;
      consumed.fetch_add(1);
      buf.release(s);
    }
  };
  std::thread c1(consumer), c2(consumer);
  uint64_t no_scan = 0;
  for (uint64_t i = 0; i < kScans; ++i) {
    Scan* s = buf.acquire();
    if (s == nullptr) {
      ++no_scan;
      continue;
    }
    s->sequence = i;
    s->x[0] = static_cast<float>(i % 1000);
    buf.publish(s);
  }
  done.store(true, std::memory_order_release);
  c1.join();
  c2.join();
  EXPECT_EQ(no_scan, 0u);
  EXPECT_EQ(order_errors.load(), 0u);
  EXPECT_EQ(buf.published(), kScans);
  EXPECT_EQ(consumed.load() + buf.dropped(), kScans);
}

}  // namespace
}  // namespace lidartag::velodyne
