// Latency samples of one pipeline stage over the last status period, and their percentiles.
// Fixed memory: the newest `capacity` samples are kept; recording never allocates.
#pragma once

#include <cstddef>
#include <mutex>
#include <vector>

namespace lidartag::daemon {

struct Percentiles {
  double p50 = 0, p90 = 0, p99 = 0, max = 0;  // same unit as the samples (ms)
  size_t count = 0;                           // samples they were computed from
};

// Nearest-rank percentiles of `values` (reordered in place). All zero when empty.
Percentiles percentiles(std::vector<double>& values);

class LatencyWindow {
 public:
  explicit LatencyWindow(size_t capacity = 1024);
  void record(double value);  // any thread
  // Percentiles of the samples since the last take(), which starts a new window.
  Percentiles take();

 private:
  std::mutex mutex_;
  std::vector<double> samples_;  // ring of the newest samples
  std::vector<double> scratch_;  // sorted copy for take()
  size_t next_ = 0, count_ = 0;
};

}  // namespace lidartag::daemon
