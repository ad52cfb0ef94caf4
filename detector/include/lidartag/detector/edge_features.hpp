// Stage 1 (paper Sec. IV-A): distance-gradient edge points per ring, eq. (1) [GD].
#pragma once

#include <vector>

#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

struct FeatureOptions {
  // l of eq. (1): the neighbours compared are l columns away. Default 1 (the paper's). Larger
  // values tolerate noisier rings but blur the edges.
  int ell = 1;
  // zeta of eq. (1), metres. Default 0.5. A tag must stand this far in front of its background;
  // smaller values find tags closer to walls but give more clutter clusters.
  float zeta_m = 0.5f;
  // "One edge among n+1 consecutive points" (the paper's n). Default 2. Drops runs of edges
  // (vegetation, mixed pixels); 0 keeps every edge point.
  int n = 2;
  // Dropouts: a neighbour without a return is replaced by the next return up to max_gap columns
  // further (compared by range difference), so that lost beams on a wall or on the ground at a
  // grazing angle are not edges (their features chain clusters across a scene). Longer gaps (sky,
  // a window) count as infinitely far, so a tag against the sky still has edges. Default 6 (1.2
  // degrees at 10 Hz); 0 treats every missing return as a jump.
  int max_gap = 6;
  // Points outside [min_range_m, max_range_m] are ignored. Defaults 0.5 m and 40 m: beyond 40 m a
  // 1.2 m tag has too few points to decode on a 32-beam sensor.
  float min_range_m = 0.5f;
  float max_range_m = 40.0f;
};

// True when the scan's columns cover the full circle, so that the last column neighbours the
// first (a complete rotation); features and fill-in then wrap around.
bool rotation_wraps(const Scan& scan);

// Appends the features of return 0 (the strongest echo) of every ring to `out` (cleared first),
// ring by ring from ring 0 upward and by column within a ring. A missing neighbour (no return
// within max_gap further columns) counts as infinitely far, so a tag against the sky still has
// edges. Only the near side of a jump is an edge point: the features lie on the foreground object.
// `max_pair_chord_m` is the longest run (metres, chord between its ends) whose two edges are
// paired as the two sides of one object (Feature::partner), so that a tag mounted as a square
// (left and right sides a full tag apart) forms one cluster; the detector passes 1.1 x the largest
// tag's diagonal; 0 disables pairing.
// `edge_buffer` is a work buffer (one ring's edge points), kept by the caller between rotations.
void detect_edge_features(const Scan& scan, const FeatureOptions& opt, float max_pair_chord_m,
                          std::vector<Feature>& out, std::vector<float>& edge_buffer);

}  // namespace lidartag::detector
