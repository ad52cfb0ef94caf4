// Portable random numbers: std::mt19937_64 is specified bit for bit by the standard, the
// std:: distributions are not (they differ between standard libraries), so the conversions to
// uniform and Gaussian variates are written here. Same seed, same numbers, on any platform.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace lidartag::sim {

class Rng {
 public:
  explicit Rng(uint64_t seed) : engine_(seed) {}

  uint64_t next_u64() { return engine_(); }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [lo, hi] (hi - lo small; the modulo bias is below 2^-50).
  int uniform_int(int lo, int hi) {
    const auto span = static_cast<uint64_t>(hi - lo) + 1;
    return lo + static_cast<int>(engine_() % span);
  }
  bool bernoulli(double p) { return p > 0.0 && uniform() < p; }
  // Standard normal by the Box-Muller transform (one of the pair; no cached state).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]: log stays finite
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  double normal(double mean, double sigma) { return sigma > 0.0 ? mean + sigma * normal() : mean; }

 private:
  std::mt19937_64 engine_;
};

}  // namespace lidartag::sim
