#include "lidartag/daemon/latency_window.hpp"

#include <gtest/gtest.h>

namespace lidartag::daemon {
namespace {

TEST(LatencyWindow, NearestRankPercentiles) {
  std::vector<double> v;
  for (int i = 100; i >= 1; --i) v.push_back(i);
  const Percentiles p = percentiles(v);
  EXPECT_EQ(p.count, 100u);
  EXPECT_EQ(p.p50, 50);
  EXPECT_EQ(p.p90, 90);
  EXPECT_EQ(p.p99, 99);
  EXPECT_EQ(p.max, 100);
  std::vector<double> one = {3.5};
  EXPECT_EQ(percentiles(one).p50, 3.5);
  std::vector<double> none;
  EXPECT_EQ(percentiles(none).max, 0);
}

TEST(LatencyWindow, TakeStartsANewWindowAndKeepsOnlyTheNewest) {
  LatencyWindow w(10);
  for (int i = 1; i <= 25; ++i) w.record(i);
  const Percentiles p = w.take();
  EXPECT_EQ(p.count, 10u);  // bounded: 16..25
  EXPECT_EQ(p.max, 25);
  EXPECT_EQ(p.p50, 20);
  EXPECT_EQ(w.take().count, 0u);
  w.record(7);
  EXPECT_EQ(w.take().p99, 7);
}

}  // namespace
}  // namespace lidartag::daemon
