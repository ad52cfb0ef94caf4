#include "lidartag/detector/cluster_validation.hpp"

#include <algorithm>
#include <cmath>

#include "lidartag/detector/edge_features.hpp"

namespace lidartag::detector {

Rejection fill_cluster(const Scan& scan, std::span<const Feature> features,
                       std::span<const int> members, const Cluster& cluster,
                       const ValidationOptions& opt, float max_extent_m,
                       std::vector<ClusterPoint>& out, std::vector<int>& ring_cols) {
  out.clear();
  if (static_cast<int>(members.size()) < opt.min_features ||
      cluster.max_ring - cluster.min_ring + 1 < opt.min_rings)
    return Rejection::kFewFeatures;
  if (cluster.max_x - cluster.min_x > max_extent_m || cluster.max_y - cluster.min_y > max_extent_m)
    return Rejection::kTooLarge;
  // Column span of the features on each ring.
  const int nr = cluster.max_ring - cluster.min_ring + 1;
  ring_cols.assign(static_cast<size_t>(2 * nr), -1);
  for (int m : members) {
    const Feature& f = features[static_cast<size_t>(m)];
    const auto r = static_cast<size_t>(2 * (f.ring - cluster.min_ring));
    if (ring_cols[r] < 0 || f.col < ring_cols[r]) ring_cols[r] = f.col;
    if (ring_cols[r + 1] < 0 || f.col > ring_cols[r + 1]) ring_cols[r + 1] = f.col;
  }
  // The features' x-y box padded by the margin.
  const float m = opt.fill_margin_m;
  const float lo_x = cluster.min_x - m, hi_x = cluster.max_x + m, lo_y = cluster.min_y - m,
              hi_y = cluster.max_y + m;
  const bool wraps = rotation_wraps(scan);
  const int cols = scan.columns;
  for (int k = 0; k < nr; ++k) {
    int& c0 = ring_cols[static_cast<size_t>(2 * k)];
    int& c1 = ring_cols[static_cast<size_t>(2 * k + 1)];
    if (c0 < 0 || c1 <= c0) {  // a ring with one feature does not cross the object
      c0 = c1 = -1;
      continue;
    }
    if (wraps && c1 - c0 > cols / 2) {  // the object straddles the start of the rotation
      const int t = c0;
      c0 = c1;
      c1 = t + cols;
    }
    // The edge test read only the ranges: the other arrays of these columns are usually not in
    // the cache. Ask for all their lines first, so that the misses of all rings overlap.
    const size_t base = scan.at(0, cluster.min_ring + k, 0);
    for (int cc = c0; cc <= c1; cc += 16) {
      const size_t i = base + static_cast<size_t>(cc >= cols ? cc - cols : cc);
      __builtin_prefetch(scan.x.data() + i);
      __builtin_prefetch(scan.y.data() + i);
      __builtin_prefetch(scan.z.data() + i);
      __builtin_prefetch(scan.intensity.data() + i);
    }
  }
  for (int k = 0; k < nr; ++k) {
    const int c0 = ring_cols[static_cast<size_t>(2 * k)];
    const int c1 = ring_cols[static_cast<size_t>(2 * k + 1)];
    if (c0 < 0) continue;
    const int ring = cluster.min_ring + k;
    const size_t base = scan.at(0, ring, 0);
    const float *xs = scan.x.data() + base, *ys = scan.y.data() + base, *zs = scan.z.data() + base,
                *rs = scan.range.data() + base;
    const uint8_t* is = scan.intensity.data() + base;
    const size_t first = out.size();
    // Columns [c0, c1], in two pieces when they cross the end of the rotation.
    const int pieces[2][2] = {{c0, std::min(c1, cols - 1)}, {0, c1 - cols}};
    for (const auto& piece : pieces) {
      for (int c = piece[0]; c <= piece[1]; ++c) {
        const float x = xs[c], y = ys[c];
        if (!(rs[c] > 0.0f) || x < lo_x || x > hi_x || y < lo_y || y > hi_y) continue;
        ClusterPoint& p = out.emplace_back();
        p.x = x;
        p.y = y;
        p.z = zs[c];
        p.intensity = static_cast<float>(is[c]);
        p.ring = ring;
        p.col = c;
      }
    }
    if (out.size() > first) {
      out[first].edge = true;
      out.back().edge = true;
    }
  }
  return Rejection::kNone;
}

size_t trim_narrow_rings(std::vector<ClusterPoint>& points, float min_width_m) {
  if (points.empty() || min_width_m <= 0.0f) return 0;
  auto narrow = [&](size_t first, size_t last) {
    const float dx = points[last].x - points[first].x, dy = points[last].y - points[first].y,
                dz = points[last].z - points[first].z;
    return dx * dx + dy * dy + dz * dz < min_width_m * min_width_m;
  };
  // From the bottom: [0, lo) are narrow rings.
  size_t lo = 0;
  while (lo < points.size()) {
    size_t end = lo;
    while (end < points.size() && points[end].ring == points[lo].ring) ++end;
    if (!narrow(lo, end - 1)) break;
    lo = end;
  }
  // From the top: [hi, size) are narrow rings.
  size_t hi = points.size();
  while (hi > lo) {
    size_t begin = hi - 1;
    while (begin > lo && points[begin - 1].ring == points[hi - 1].ring) --begin;
    if (!narrow(begin, hi - 1)) break;
    hi = begin;
  }
  const size_t dropped = lo + (points.size() - hi);
  if (dropped == 0) return 0;
  points.erase(points.begin() + static_cast<std::ptrdiff_t>(hi), points.end());
  points.erase(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(lo));
  return dropped;
}

double max_tag_points(std::span<const ClusterPoint> points, double t_max,
                      double horizontal_resolution_rad) {
  if (points.empty() || horizontal_resolution_rad <= 0.0) return 0.0;
  double sum = 0.0;
  int rings = 0, last = -1;
  for (const auto& p : points) {
    sum += std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
    rings += p.ring != last ? 1 : 0;
    last = p.ring;
  }
  const double d = sum / static_cast<double>(points.size());
  // M t sqrt(2) / (D sin theta): the tag's diagonal over the spacing of two returns, per ring.
  return rings * t_max * std::sqrt(2.0) / (d * std::sin(horizontal_resolution_rad));
}

Rejection check_point_counts(std::span<const ClusterPoint> points, int min_points, double t_max,
                             double horizontal_resolution_rad, const ValidationOptions& opt) {
  const auto n = static_cast<int>(points.size());
  if (n < min_points) return Rejection::kTooFewPoints;
  if (n > opt.max_points_scale * max_tag_points(points, t_max, horizontal_resolution_rad))
    return Rejection::kTooManyPoints;
  return Rejection::kNone;
}

int rings_in(std::span<const ClusterPoint> points) {
  int n = 0, last = -1;
  for (const auto& p : points)
    if (p.ring != last) {
      ++n;
      last = p.ring;
    }
  return n;
}

int testable_points(std::span<const ClusterPoint> points, const ValidationOptions& opt) {
  const int two_l = 2 * std::max(opt.gi_ell, 1);
  int n = 0;
  size_t first = 0;
  for (size_t i = 1; i <= points.size(); ++i) {
    if (i < points.size() && points[i].ring == points[first].ring) continue;
    n += std::max(0, static_cast<int>(i - first) - two_l);
    first = i;
  }
  return n;
}

int track_boundary_bound(int testable, int rings, int psi, int track_bound,
                         const ValidationOptions& opt) {
  const float step = std::max(opt.track_testable_per_transition, 1e-3f);
  int bound = std::min(
      track_bound,
      static_cast<int>(std::ceil(static_cast<float>(std::max(testable, 0)) / step - 1e-4f)));
  if (opt.track_transitions_per_ring > 0.0f)
    bound = std::min(bound, static_cast<int>(std::ceil(opt.track_transitions_per_ring *
                                                       static_cast<float>(std::max(rings, 0)))));
  return std::max((psi + 3) / 4, bound);
}

int count_boundary_points(std::span<const ClusterPoint> points, const ValidationOptions& opt) {
  if (points.empty()) return 0;
  double mean = 0.0;
  for (const auto& p : points) mean += p.intensity;
  mean /= static_cast<double>(points.size());
  const auto thr = std::max(static_cast<float>(opt.boundary_ratio * mean), opt.min_intensity_step);
  const auto l = static_cast<size_t>(std::max(opt.gi_ell, 1));
  int count = 0;
  // Points come ring by ring: i - l and i + l on the ring of i means all three are on one ring.
  for (size_t i = l; i + l < points.size(); ++i) {
    const ClusterPoint &a = points[i - l], &p = points[i], &b = points[i + l];
    // eq. (5); counting the side where the step is ahead gives one point per transition.
    const float g = std::fabs(b.intensity - p.intensity) - std::fabs(a.intensity - p.intensity);
    count += ((a.ring == p.ring) & (b.ring == p.ring) & (g > thr)) ? 1 : 0;
  }
  return count;
}

}  // namespace lidartag::detector
