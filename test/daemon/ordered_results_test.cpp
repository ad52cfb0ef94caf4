// The reorder stage: results leave in taking order whatever order detection finishes in, and the
// number of rotations in flight is bounded.
#include "lidartag/daemon/ordered_results.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <deque>
#include <mutex>
#include <random>
#include <thread>

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

TEST(OrderedResults, PublishesInTakingOrderWhenDetectionFinishesOutOfOrder) {
  OrderedResults ordered(3, 2);
  std::vector<Scan> scans(3);
  for (size_t i = 0; i < 3; ++i) scans[i].sequence = 10 + i;
  size_t next = 0;
  auto pop = [&]() -> Scan* { return next < scans.size() ? &scans[next++] : nullptr; };
  auto* a = ordered.take(pop, 1);
  auto* b = ordered.take(pop, 2);
  auto* c = ordered.take(pop, 3);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(ordered.take(pop, 4), nullptr);  // no detector free: nothing is popped
  EXPECT_EQ(next, 3u);
  EXPECT_EQ(ordered.oldest_in_detection_ns(), 1);
  for (auto* s : {a, b, c}) s->result.sequence = s->scan->sequence;
  ordered.complete(c);
  ordered.complete(b);
  EXPECT_EQ(ordered.next_ready(1ms), nullptr);  // a is still in detection
  EXPECT_EQ(ordered.oldest_in_detection_ns(), 1);
  ordered.complete(a);
  EXPECT_EQ(ordered.oldest_in_detection_ns(), 0);
  std::vector<uint64_t> order;
  while (auto* s = ordered.next_ready(1ms)) {
    order.push_back(s->result.sequence);
    ordered.recycle(s);
  }
  EXPECT_EQ(order, (std::vector<uint64_t>{10, 11, 12}));
  EXPECT_EQ(ordered.in_use(), 0u);
}

TEST(OrderedResults, BoundedWhenThePublisherFallsBehind) {
  OrderedResults ordered(2, 1);  // 3 slots
  Scan scan;
  auto pop = [&]() -> Scan* { return &scan; };
  std::vector<OrderedResults::Slot*> taken;
  while (auto* s = ordered.take(pop, 0)) {
    ordered.complete(s);  // detected at once, never published
    taken.push_back(s);
    ASSERT_LE(taken.size(), 3u);
  }
  EXPECT_EQ(taken.size(), 3u);
  EXPECT_FALSE(ordered.has_free_slot());
  auto* first = ordered.next_ready(1ms);
  ASSERT_EQ(first, taken[0]);
  ordered.recycle(first);
  EXPECT_TRUE(ordered.has_free_slot());
}

TEST(OrderedResults, ManyThreadsRandomDelaysKeepOrderAndLoseNothing) {
  constexpr int kWorkers = 4, kRotations = 400;
  OrderedResults ordered(kWorkers, 3);
  std::vector<Scan> scans(kRotations);
  for (int i = 0; i < kRotations; ++i)
    scans[static_cast<size_t>(i)].sequence = static_cast<uint64_t>(i);
  std::atomic<int> next{0};
  auto pop = [&]() -> Scan* {
    const int i = next.load();
    if (i >= kRotations) return nullptr;
    next.store(i + 1);  // take() serialises pops
    return &scans[static_cast<size_t>(i)];
  };
  std::vector<std::thread> workers;
  for (int w = 0; w < kWorkers; ++w) {
    workers.emplace_back([&, w] {
      std::mt19937 rng(static_cast<unsigned>(w));
      while (next.load() < kRotations) {
        auto* slot = ordered.take(pop, 1);
        if (slot == nullptr) {
          std::this_thread::yield();
          continue;
        }
        slot->result.sequence = slot->scan->sequence;
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 300));
        ordered.complete(slot);
      }
    });
  }
  std::vector<uint64_t> published;
  while (published.size() < static_cast<size_t>(kRotations)) {
    if (auto* s = ordered.next_ready(100ms)) {
      published.push_back(s->result.sequence);
      ordered.recycle(s);
    }
  }
  for (auto& t : workers) t.join();
  ASSERT_EQ(published.size(), static_cast<size_t>(kRotations));
  EXPECT_TRUE(std::is_sorted(published.begin(), published.end()));
  EXPECT_EQ(published.back(), static_cast<uint64_t>(kRotations - 1));
}

}  // namespace
}  // namespace lidartag::daemon
