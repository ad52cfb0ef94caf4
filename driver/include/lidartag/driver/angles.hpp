// Azimuth arithmetic shared by the assembly and the vendors' decoders.
#pragma once

#include <cmath>
#include <cstdint>

namespace lidartag::driver {

// Degrees into [0, 360). Differences of two azimuths in [0, 360) need one add, not a division
// (they are wrapped per column).
[[gnu::cold]] inline double wrap360_far(double deg) {
  deg = std::fmod(deg, 360.0);
  return deg < 0 ? deg + 360.0 : deg;
}
inline double wrap360(double deg) {
  if (deg >= 0 && deg < 360.0) return deg;
  if (deg < 0 && deg >= -360.0) return deg + 360.0;
  return wrap360_far(deg);  // out of line: the common cases stay small enough to inline
}

// std::llround(v) without the library call in the common case (the per-column timestamps): for
// |v| < 2^52, v minus its integer part is exact.
inline int64_t round_half_away(double v) {
  if (!(std::abs(v) < 0x1p52)) return std::llround(v);  // huge or NaN: the library's answer
  const auto i = static_cast<int64_t>(v);
  const double f = v - static_cast<double>(i);
  return i + static_cast<int64_t>(f >= 0.5) - static_cast<int64_t>(f <= -0.5);
}

// For angles already within one turn of [0, 360): the per-point path. Plain selects, so that the
// loops calling it still vectorise.
inline float wrap_near(float deg) {
  deg = deg < 0.0f ? deg + 360.0f : deg;
  return deg >= 360.0f ? deg - 360.0f : deg;
}

}  // namespace lidartag::driver
