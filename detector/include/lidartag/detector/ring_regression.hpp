// Scans without ring numbers (a PCD from another tool): rings regressed from elevation angles
// (paper Sec. IV-B, remark), so that an unorganised cloud becomes a ring-major Scan.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

// Two points of one ring this close in azimuth and elevation, degrees, are two echoes of one
// firing (a dual-return cloud): a sensor's firings are at least 0.05 degrees apart.
inline constexpr double kSameFiringDeg = 0.01;

struct CloudPoint {
  float x = 0, y = 0, z = 0;  // metres, sensor frame
  float intensity = 0;        // 0..255
  int ring = -1;              // the point's ring when the file has one (0 = lowest), else -1
  float time_s = 0;           // seconds from the rotation start (kept in the scan's cell)
};

struct RingRegressionOptions {
  // Beam elevations in degrees (any order). Empty: estimated from the cloud with `rings` beams.
  std::vector<double> elevations_deg;
  // Number of beams when the elevations are not given. Default 0 (then elevations are required).
  int rings = 0;
  // Width of a column of the organised scan, degrees of azimuth. Default 0.2 (a Velodyne at
  // 10 Hz); use the sensor's horizontal resolution.
  double horizontal_resolution_deg = 0.2;
};

// The `rings` beam elevations (ascending, degrees) of a single-axis spinning sensor: the cloud's
// elevation angles atan(z / sqrt(x^2 + y^2)) split at the rings - 1 widest gaps, each group's mean.
// Returns an empty vector when the cloud has fewer distinct elevations than rings.
std::vector<double> estimate_elevations(std::span<const CloudPoint> cloud, int rings);

// Ring of each point: the nearest beam elevation (ring 0 = lowest); column: the nearest multiple
// of the horizontal resolution in azimuth (azimuth
// clockwise from +x, as the sensor's). A cell hit twice keeps the nearer point. `out` is resized
// when its dimensions differ. Returns false (and leaves `out` empty) when no elevations are given
// or can be estimated, or the resolution is outside [0.001, 360] degrees. Points with a
// non-finite or zero range are skipped; a NaN intensity reads as 0. `echoes`, when given, counts
// the points that met a point of their ring in the same direction (within 0.01 degrees: two
// echoes of one firing, a dual-return cloud), of which the nearer was kept.
bool regress_rings(std::span<const CloudPoint> cloud, const RingRegressionOptions& opt, Scan& out,
                   size_t* echoes = nullptr);

// A cloud whose points carry their ring (CloudPoint::ring, e.g. a PCD with a `ring` field) as a
// `rings` x columns scan, columns as in regress_rings. Points whose ring is outside [0, rings) are
// dropped. Returns false (and leaves `out` empty) when rings <= 0 or the resolution is outside
// [0.001, 360] degrees. `echoes` as in regress_rings.
bool organise_rings(std::span<const CloudPoint> cloud, int rings, double horizontal_resolution_deg,
                    Scan& out, size_t* echoes = nullptr);

}  // namespace lidartag::detector
