#include "lidartag/daemon/latency_window.hpp"

#include <algorithm>
#include <cmath>

namespace lidartag::daemon {

Percentiles percentiles(std::vector<double>& values) {
  Percentiles p;
  p.count = values.size();
  if (values.empty()) return p;
  std::sort(values.begin(), values.end());
  // Nearest rank: the smallest value with at least q of the samples at or below it.
  auto rank = [&](double q) {
    const auto k = static_cast<size_t>(std::ceil(q * static_cast<double>(values.size())));
    return values[std::clamp<size_t>(k, 1, values.size()) - 1];
  };
  p.p50 = rank(0.50);
  p.p90 = rank(0.90);
  p.p99 = rank(0.99);
  p.max = values.back();
  return p;
}

LatencyWindow::LatencyWindow(size_t capacity) : samples_(capacity > 0 ? capacity : 1) {
  scratch_.reserve(samples_.size());
}

void LatencyWindow::record(double value) {
  std::lock_guard lock(mutex_);
  samples_[next_] = value;
  next_ = (next_ + 1) % samples_.size();
  count_ = std::min(count_ + 1, samples_.size());
}

Percentiles LatencyWindow::take() {
  std::lock_guard lock(mutex_);
  scratch_.assign(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(count_));
  count_ = 0;
  next_ = 0;
  return percentiles(scratch_);
}

}  // namespace lidartag::daemon
