// The daemon keeps host times as int64 nanoseconds of the steady clock and speaks seconds in its
// options and messages; these are the two conversions.
#pragma once

#include <cstdint>

namespace lidartag::daemon {

constexpr double seconds(int64_t ns) {
  return static_cast<double>(ns) * 1e-9;
}

constexpr int64_t nanoseconds(double seconds) {
  return static_cast<int64_t>(seconds * 1e9);
}

}  // namespace lidartag::daemon
