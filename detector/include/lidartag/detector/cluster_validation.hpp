// Stage 3 (paper Sec. IV-C): fill-in of a cluster from the scan, point-count bounds, eqs. (3) and
// (4), and payload boundary points, eq. (5) [GI] with the bound eq. (6) [psi].
#pragma once

#include <span>
#include <vector>

#include "lidartag/detector/clustering.hpp"
#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

struct ValidationOptions {
  // Fewest features and rings a cluster needs to be looked at. Defaults 4 and 3: a tag crossed by
  // fewer rings cannot be decoded.
  int min_features = 4;
  int min_rings = 3;
  // Lower bound eta = min_returns_per_cell * total_width^2 (the paper assumes 5 returns per cell,
  // i.e. 5 (d+4)^2; the published code 2 (d+2)^2). Default 1.0: a 1.2 m tag16h5 at 16 m on a
  // VLP-32C returns about 4 points per cell, at 20 m and 45 degrees fewer than 2.
  float min_returns_per_cell = 1.0f;
  // Upper bound = max_points_scale * M t sqrt(2) / (D sin theta) (M rings on the cluster, D its
  // mean range, theta the horizontal resolution). Default 1.3 (slack for range noise).
  float max_points_scale = 1.3f;
  // Fill-in: points within this distance (metres) outside the features' x-y box are kept.
  // Default 0.02.
  float fill_margin_m = 0.02f;
  // eq. (5): l (columns) and the threshold, a fraction of the cluster's mean intensity (default
  // 0.5, as published) but at least min_intensity_step (default 8 of 255).
  int gi_ell = 1;
  float boundary_ratio = 0.5f;
  float min_intensity_step = 8.0f;
  // psi >= boundary_scale * 2 (d + 2) payload boundary points (d payload cells across).
  // Default 1 (the paper's bound).
  float boundary_scale = 1.0f;
  // A cluster below that bound but with at least track_boundary_scale * 2 (d + 2) boundary points
  // is still fitted and decoded, as evidence for a tracker (Candidate::track_only), never a
  // detection of its own: a sparse rotation misses a few transitions of a tag whose ID several
  // rotations together can show. Default 0.75; a value at or above boundary_scale turns it off.
  float track_boundary_scale = 0.75f;
  // The far edge (a tag turned away near the end of its range, issue 33): a cluster with fewer
  // points than eq. (3) asks but at least track_returns_per_cell * total_width^2 goes on the same
  // way, as evidence for a tracker only; its boundary bound is then track_boundary_bound's, which
  // depends on the rings crossing it. Default 0.5 (32 points for tag16h5: a 1.2 m tag16h5 at 32 m
  // and 45 degrees on a VLP-32C returns 35-50); a value at or above min_returns_per_cell turns
  // it off.
  float track_returns_per_cell = 0.5f;
  // track_boundary_bound, the tracks' boundary bound: one payload boundary point asked per
  // track_testable_per_transition points where eq. (5) can fire (testable_points). Default 8: a
  // 1.2 m tag16h5 at 28 m and 45 degrees on a VLP-32C (8-11 rings, 29-45 testable points) shows
  // 3-19 transitions, one per 3.5 testable points at the median, but fewer than one per 6 in 4 %
  // of its clusters, which with 6 were no evidence at all (bench_tracker --cell vlp32c:28:45
  // --trace).
  float track_testable_per_transition = 8.0f;
  // ... and at most track_transitions_per_ring per ring crossing the cluster: a ring shows the
  // transitions of the rows it crosses, whatever its returns (a VLP-16's tag at 10 m and 45
  // degrees: 5 rings of 20 returns, 8-17 transitions, against a bound of 9). Default 1.5; 0: no
  // such cap.
  float track_transitions_per_ring = 1.5f;
  // Rings at the top and bottom of a cluster whose run is narrower than this fraction of the
  // smallest tag size are dropped before the point counts: the post of an easel or a pole under
  // the tag (in the tag's plane, so the plane fit keeps it) would otherwise bend the outline and
  // pull the pose down. Default 0.25: a diamond loses its two tips (3 % of its area), posts up to a
  // quarter of the tag's width are removed. 0 keeps every ring.
  float min_ring_width = 0.25f;
};

// Fill-in: the points of return 0 on each ring of `cluster` between that ring's first and last
// feature (`members` indexes `features`) and inside the features' x-y box padded by
// fill_margin_m. Points come out ring by ring, by column; the first and last of a ring are marked
// `edge`. `ring_cols` is a work buffer. Returns kNone, kFewFeatures or kTooLarge.
Rejection fill_cluster(const Scan& scan, std::span<const Feature> features,
                       std::span<const int> members, const Cluster& cluster,
                       const ValidationOptions& opt, float max_extent_m,
                       std::vector<ClusterPoint>& out, std::vector<int>& ring_cols);

// Drops the rings at the bottom and at the top of `points` (ring by ring, as fill_cluster emits
// them) whose run, the chord from the ring's first to its last point, is shorter than
// `min_width_m`; stops at the first wider ring from each end. Returns the points dropped.
size_t trim_narrow_rings(std::vector<ClusterPoint>& points, float min_width_m);

// The paper's upper bound on the returns of a tag of size t_max at the cluster's distance.
double max_tag_points(std::span<const ClusterPoint> points, double t_max,
                      double horizontal_resolution_rad);

// The point-count gates of a cluster after fill-in: at least `min_points` (eq. (3), the family's
// lower bound) and at most max_points_scale times max_tag_points (eq. (4), for the largest tag
// t_max at the cluster's distance). Returns kNone, kTooFewPoints or kTooManyPoints.
Rejection check_point_counts(std::span<const ClusterPoint> points, int min_points, double t_max,
                             double horizontal_resolution_rad, const ValidationOptions& opt);

// Number of rings holding points (M in the paper's upper bound).
int rings_in(std::span<const ClusterPoint> points);

// The points of `points` (ring by ring, as fill_cluster emits them) at which eq. (5) can be
// evaluated: those with l = opt.gi_ell points of their ring on both sides, sum over rings of
// max(0, n_ring - 2 l).
int testable_points(std::span<const ClusterPoint> points, const ValidationOptions& opt);

// The track-only boundary bound of a cluster with `testable` points where eq. (5) can fire
// (testable_points) on `rings` rings (rings_in), for a family whose eq. (6) bound is
// psi = 2 (d + 2). Eq. (6) assumes each payload row is crossed by a ring that shows its two
// transitions; a ring with few returns on a turned tag (its white border one return or none, its
// end points untestable) shows fewer: at the far edge (VLP-32C, 1.2 m tag at 28-32 m, 45 degrees:
// 4-6 returns per ring, 2-4 testable) about one transition per ring, below that in half the
// rotations; and a tag crossed by few rings shows only their rows' transitions. The bound asks for
// one per opt.track_testable_per_transition testable points and at most
// opt.track_transitions_per_ring per ring (when that is positive), never above `track_bound` (the
// track_boundary_scale bound, which a well-sampled cluster keeps) and never below psi / 4:
// max(ceil(psi / 4), min(track_bound, ceil(testable / rate), ceil(per_ring * rings))).
int track_boundary_bound(int testable, int rings, int psi, int track_bound,
                         const ValidationOptions& opt);

// eq. (5) along each ring: grad I = |I_{i+l} - I_i| - |I_{i-l} - I_i|; a point whose gradient
// exceeds the threshold is a payload boundary point. Returns their number.
int count_boundary_points(std::span<const ClusterPoint> points, const ValidationOptions& opt);

}  // namespace lidartag::detector
