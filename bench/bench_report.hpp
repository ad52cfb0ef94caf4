// What the benchmarks that write a report (bench_tracker, bench_size_check) print beside their
// figures: numbers to a fixed precision, quantiles, and the machine they ran on and how loaded it
// was.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace lidartag::bench_report {

inline std::string fmt(double v, int digits) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// The element at fraction q of the sorted values (q 0.5: the median, the upper one of an even
// count); NaN for none.
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

inline double median(std::vector<double> v) {
  return quantile(std::move(v), 0.5);
}

// The CPU's model and the load averages, for the figures' context.
inline std::string machine() {
  std::string cpu = "unknown CPU", load = "?";
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);)
    if (line.rfind("model name", 0) == 0) {
      cpu = line.substr(line.find(':') + 2);
      break;
    }
  std::ifstream avg("/proc/loadavg");
  double l1 = 0, l5 = 0, l15 = 0;
  if (avg >> l1 >> l5 >> l15) load = fmt(l1, 2) + ", " + fmt(l5, 2) + ", " + fmt(l15, 2);
  return cpu + " (" + std::to_string(std::thread::hardware_concurrency()) +
         " cores), load average at the end " + load;
}

}  // namespace lidartag::bench_report
