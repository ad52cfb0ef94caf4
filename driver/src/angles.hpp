// Azimuth arithmetic shared by the decoder and the batcher (private to the driver).
#pragma once

#include <cmath>

namespace lidartag::velodyne {

// Degrees into [0, 360). Differences of two azimuths in [0, 360) need one add, not a division
// (they are wrapped per column).
inline double wrap360(double deg) {
  if (deg >= 0 && deg < 360.0) return deg;
  if (deg < 0 && deg >= -360.0) return deg + 360.0;
  deg = std::fmod(deg, 360.0);
  return deg < 0 ? deg + 360.0 : deg;
}

// For angles already within one turn of [0, 360): the per-point path. Plain selects, so that the
// loops calling it still vectorise.
inline float wrap_near(float deg) {
  deg = deg < 0.0f ? deg + 360.0f : deg;
  return deg >= 360.0f ? deg - 360.0f : deg;
}

}  // namespace lidartag::velodyne
