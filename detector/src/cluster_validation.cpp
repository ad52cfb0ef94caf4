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
  const float m = opt.fill_margin_m;
  const bool wraps = rotation_wraps(scan);
  const int cols = scan.columns;
  for (int k = 0; k < nr; ++k) {
    int c0 = ring_cols[static_cast<size_t>(2 * k)];
    int c1 = ring_cols[static_cast<size_t>(2 * k + 1)];
    if (c0 < 0 || c1 <= c0) continue;   // a ring with one feature does not cross the object
    if (wraps && c1 - c0 > cols / 2) {  // the object straddles the start of the rotation
      const int t = c0;
      c0 = c1;
      c1 = t + cols;
    }
    const int ring = cluster.min_ring + k;
    const size_t first = out.size();
    for (int cc = c0; cc <= c1; ++cc) {
      const int c = cc >= cols ? cc - cols : cc;
      const size_t i = scan.at(0, ring, c);
      if (!scan.valid(i)) continue;
      const float x = scan.x[i], y = scan.y[i];
      if (x < cluster.min_x - m || x > cluster.max_x + m || y < cluster.min_y - m ||
          y > cluster.max_y + m)
        continue;
      ClusterPoint p;
      p.x = x;
      p.y = y;
      p.z = scan.z[i];
      p.intensity = static_cast<float>(scan.intensity[i]);
      p.ring = ring;
      p.col = c;
      out.push_back(p);
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
  for (const auto& p : points)
    sum += std::sqrt(double{p.x} * p.x + double{p.y} * p.y + double{p.z} * p.z);
  const double d = sum / static_cast<double>(points.size());
  // M t sqrt(2) / (D sin theta): the tag's diagonal over the spacing of two returns, per ring.
  return rings_in(points) * t_max * std::sqrt(2.0) / (d * std::sin(horizontal_resolution_rad));
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

int count_boundary_points(std::span<const ClusterPoint> points, const ValidationOptions& opt) {
  if (points.empty()) return 0;
  double mean = 0.0;
  for (const auto& p : points) mean += p.intensity;
  mean /= static_cast<double>(points.size());
  const auto thr = std::max(static_cast<float>(opt.boundary_ratio * mean), opt.min_intensity_step);
  const auto l = static_cast<size_t>(std::max(opt.gi_ell, 1));
  int count = 0;
  size_t begin = 0;
  while (begin < points.size()) {
    size_t end = begin;
    while (end < points.size() && points[end].ring == points[begin].ring) ++end;
    for (size_t i = begin + l; i + l < end; ++i) {
      // eq. (GI); counting the side where the step is ahead gives one point per transition.
      const float g = std::fabs(points[i + l].intensity - points[i].intensity) -
                      std::fabs(points[i - l].intensity - points[i].intensity);
      if (g > thr) ++count;
    }
    begin = end;
  }
  return count;
}

}  // namespace lidartag::detector
