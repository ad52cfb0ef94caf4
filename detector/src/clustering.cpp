#include "lidartag/detector/clustering.hpp"

#include <algorithm>
#include <cmath>

namespace lidartag::detector {
namespace {

int find_root(std::vector<Cluster>& cs, int i) {
  while (cs[static_cast<size_t>(i)].parent >= 0) {
    const int p = cs[static_cast<size_t>(i)].parent;
    const int gp = cs[static_cast<size_t>(p)].parent;
    if (gp >= 0) cs[static_cast<size_t>(i)].parent = gp;  // path halving
    i = p;
  }
  return i;
}

void absorb(Cluster& into, const Cluster& from) {
  into.min_x = std::min(into.min_x, from.min_x);
  into.max_x = std::max(into.max_x, from.max_x);
  into.min_y = std::min(into.min_y, from.min_y);
  into.max_y = std::max(into.max_y, from.max_y);
  into.min_ring = std::min(into.min_ring, from.min_ring);
  into.max_ring = std::max(into.max_ring, from.max_ring);
  into.features += from.features;
}

// The cluster of one feature.
Cluster single(const Feature& f) {
  Cluster c;
  c.min_x = c.max_x = f.x;
  c.min_y = c.max_y = f.y;
  c.min_ring = c.max_ring = f.ring;
  c.features = 1;
  return c;
}

// Splits cluster `c` (too large), whose features are `members` (in feature order), into the
// single-linkage components of its features: two features link when both x and y differ by at most
// tau and their rings by at most ring_gap, or when they are partners (the two ends of one ring
// run). New clusters are appended, one per component in the order of its first feature; `c` is
// retired. `where` maps a feature to its position in `members`, -1 for the others.
void split_cluster(std::span<const Feature> features, float tau, int ring_gap, int c,
                   std::span<const int> members, std::span<const int> where,
                   std::vector<Cluster>& clusters, std::vector<int>& labels) {
  thread_local std::vector<int> parent, root_cluster, groups;
  thread_local std::vector<std::pair<float, int>> by_x;  // (x, member), per ring
  const size_t m = members.size();
  parent.resize(m);
  for (size_t i = 0; i < m; ++i) parent[i] = static_cast<int>(i);
  // The root of a component is its first member: unite keeps the smaller root.
  auto root = [&](int i) {
    while (parent[static_cast<size_t>(i)] != i) {
      parent[static_cast<size_t>(i)] = parent[static_cast<size_t>(parent[static_cast<size_t>(i)])];
      i = parent[static_cast<size_t>(i)];
    }
    return i;
  };
  auto unite = [&](int a, int b) {
    a = root(a);
    b = root(b);
    if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
  };
  auto feature = [&](size_t i) -> const Feature& {
    return features[static_cast<size_t>(members[i])];
  };
  // The fast path needs the rings in order and x that sorts (no NaN, which a partner link can
  // bring in).
  bool ascending = true;
  for (size_t i = 0; i < m && ascending; ++i)
    ascending = !std::isnan(feature(i).x) && (i == 0 || feature(i - 1).ring <= feature(i).ring);
  if (ascending) {
    // Features come ring by ring: a feature links to those of its own and the ring_gap rings
    // below whose x is within tau, found by binary search in each ring's members sorted by x (a
    // window a little wider than tau, then the exact test).
    groups.clear();  // the start of each ring's members, and m
    by_x.resize(m);
    for (size_t i = 0; i < m; ++i) {
      if (i == 0 || feature(i).ring != feature(i - 1).ring) groups.push_back(static_cast<int>(i));
      by_x[i] = {feature(i).x, static_cast<int>(i)};
    }
    groups.push_back(static_cast<int>(m));
    for (size_t g = 0; g + 1 < groups.size(); ++g)
      std::sort(by_x.begin() + groups[g], by_x.begin() + groups[g + 1]);
    const double reach = static_cast<double>(tau) * (1.0 + 1e-5);
    for (size_t g = 0; g + 1 < groups.size(); ++g) {
      const int ring = feature(static_cast<size_t>(groups[g])).ring;
      size_t first = g;  // the lowest ring within reach
      while (first > 0 && feature(static_cast<size_t>(groups[first - 1])).ring >= ring - ring_gap)
        --first;
      for (int i = groups[g]; i < groups[g + 1]; ++i) {
        const Feature& f = feature(static_cast<size_t>(i));
        const double lo = f.x - reach, hi = f.x + reach;
        for (size_t h = first; h <= g; ++h) {
          const auto end = by_x.begin() + groups[h + 1];
          for (auto it = std::lower_bound(
                   by_x.begin() + groups[h], end, lo,
                   [](const std::pair<float, int>&e, double v) { return double(e.first) < v; });
               it != end && double(it->first) <= hi; ++it) {
            const Feature& e = feature(static_cast<size_t>(it->second));
            if (std::abs(e.x - f.x) <= tau && std::abs(e.y - f.y) <= tau) unite(i, it->second);
          }
        }
      }
    }
  } else {
    for (size_t i = 0; i < m; ++i) {
      const Feature& f = feature(i);
      for (size_t j = i; j-- > 0;) {
        const Feature& e = feature(j);
        if (e.ring < f.ring - ring_gap) break;
        if (std::abs(e.x - f.x) <= tau && std::abs(e.y - f.y) <= tau)
          unite(static_cast<int>(i), static_cast<int>(j));
      }
    }
  }
  for (size_t i = 0; i < m; ++i) {
    const Feature& f = feature(i);
    if (f.partner >= 0 && where[static_cast<size_t>(f.partner)] >= 0)
      unite(static_cast<int>(i), where[static_cast<size_t>(f.partner)]);
  }
  root_cluster.assign(m, -1);
  for (size_t i = 0; i < m; ++i) {
    const int r = root(static_cast<int>(i));
    const Feature& f = feature(i);
    int& cl = root_cluster[static_cast<size_t>(r)];
    if (cl < 0) {
      clusters.push_back(single(f));
      cl = static_cast<int>(clusters.size()) - 1;
    } else {
      absorb(clusters[static_cast<size_t>(cl)], single(f));
    }
    labels[static_cast<size_t>(members[i])] = cl;
  }
  clusters[static_cast<size_t>(c)].parent = root_cluster[0];  // retired
}

// The linkage's index: which live clusters a feature may link to, by azimuth. A feature inside a
// cluster's tau-padded x-y box sees the box within the box's azimuth span from the sensor, so each
// live cluster is listed in the azimuth bins of its padded box's span (one bin more on each side
// for rounding) and a feature is tested against the clusters of its own bin only: the same
// clusters pass the test as when every live cluster is tested, in any order, and the cluster that
// takes the feature is the lowest-numbered of them, as in a test of every cluster in order. The
// azimuth is the "diamond angle", a monotone stand-in in [0, 4) without trigonometry. Clusters
// merged or out of ring reach are dropped from a bin when a feature visits it; a cluster's span
// only grows (its box only grows), so only the new bins are added as it grows.
class AzimuthIndex {
 public:
  static constexpr int kBins = 512;

  void clear() {
    bins_.resize(kBins);
    for (auto& b : bins_) b.clear();
    lo_.clear();
    hi_.clear();
  }

  // The bin of a feature at (x, y), -1 when not finite (no azimuth).
  static int bin_of(float x, float y) {
    if (!std::isfinite(x) || !std::isfinite(y)) return -1;
    if (x == 0.0f && y == 0.0f) return 0;  // only boxes that hold the sensor (every bin) hold it
    const double p = pseudo_angle(x, y) * (kBins / 4.0);
    return wrap(static_cast<int>(std::floor(p)));
  }

  // The live clusters listed in bin `b`.
  std::vector<int>& bin(int b) { return bins_[static_cast<size_t>(b)]; }

  // Lists cluster `c` (a new one, or one whose box grew) in the bins of its box padded by `tau`.
  void update(int c, const Cluster& cl, float tau) {
    const auto u = static_cast<size_t>(c);
    if (lo_.size() <= u) {
      lo_.resize(u + 1, 0);
      hi_.resize(u + 1, -1);  // listed nowhere
    }
    int a = 0, b = kBins - 1;
    span_of(cl, tau, a, b);
    const int old_lo = lo_[u], old_hi = hi_[u];
    if (old_hi >= old_lo) {
      // The new span contains the old one (up to rounding): unwrap it next to the old one and join.
      const int shift = static_cast<int>(
          std::lround(static_cast<double>((old_lo + old_hi) - (a + b)) / (2.0 * kBins)));
      a = std::min(a + shift * kBins, old_lo);
      b = std::max(b + shift * kBins, old_hi);
      if (b - a + 1 >= kBins) {  // the whole turn: every bin the old span misses
        a = old_hi + 1 - kBins;
        b = old_hi;
      }
      for (int i = a; i < old_lo; ++i) bins_[static_cast<size_t>(wrap(i))].push_back(c);
      for (int i = old_hi + 1; i <= b; ++i) bins_[static_cast<size_t>(wrap(i))].push_back(c);
    } else {
      for (int i = a; i <= b; ++i) bins_[static_cast<size_t>(wrap(i))].push_back(c);
    }
    const int w = wrap(a);
    lo_[u] = w;
    hi_[u] = w + (b - a);
  }

 private:
  static int wrap(int i) { return ((i % kBins) + kBins) % kBins; }

  // Monotone in the azimuth: 0 on +x, 1 on +y, 2 on -x, 3 on -y, below 4 just under +x.
  static double pseudo_angle(double x, double y) {
    const double t = y / (std::abs(x) + std::abs(y));
    if (x >= 0) return y >= 0 ? t : 4.0 + t;
    return 2.0 - t;
  }

  // The bins [a, b] (b - a < kBins, a may be negative) of the padded box's azimuth span, or the
  // whole turn when the box comes within a millimetre of the sensor, is not finite or reaches
  // beyond 10 km (where rounding could make the span wrong).
  static void span_of(const Cluster& cl, float tau, int& a, int& b) {
    // The padded box as eq. (2)'s comparisons compute it.
    const double x0 = cl.min_x - tau, x1 = cl.max_x + tau, y0 = cl.min_y - tau, y1 = cl.max_y + tau;
    constexpr double kNear = 1e-3, kFar = 1e4;
    a = 0;
    b = kBins - 1;
    if (!(x0 >= -kFar && x1 <= kFar && y0 >= -kFar && y1 <= kFar)) return;  // NaN too
    if (x0 <= kNear && x1 >= -kNear && y0 <= kNear && y1 >= -kNear) return;
    // The box does not hold the sensor, so its corners span less than half a turn (2): their
    // offsets from the first corner, wrapped to (-2, 2], bound the span.
    const double p0 = pseudo_angle(x0, y0);
    double lo = 0, hi = 0;
    for (const auto& [x, y] : {std::pair{x1, y0}, std::pair{x0, y1}, std::pair{x1, y1}}) {
      double d = pseudo_angle(x, y) - p0;
      if (d > 2.0) d -= 4.0;
      if (d <= -2.0) d += 4.0;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
    a = static_cast<int>(std::floor((p0 + lo) * (kBins / 4.0))) - 1;
    b = static_cast<int>(std::floor((p0 + hi) * (kBins / 4.0))) + 1;
    if (b - a + 1 >= kBins) b = a + kBins - 1;
  }

  std::vector<std::vector<int>> bins_;
  std::vector<int> lo_, hi_;  // per cluster: the bins it is listed in, lo_..hi_ (wrapped)
};

}  // namespace

void cluster_features(std::span<const Feature> features, float tau, float max_extent_m,
                      const ClusterOptions& opt, std::vector<Cluster>& clusters,
                      std::vector<int>& labels) {
  clusters.clear();
  labels.assign(features.size(), -1);
  const int gap = opt.ring_gap;
  // The clusters a feature may still link to (see AzimuthIndex). Features come ring by ring, so a
  // cluster whose ring span ends more than ring_gap below the feature's ring is out of reach for
  // good: it is dropped from the bins. The index is rebuilt when that reasoning does not hold: the
  // rings go down, or a partner link revives a dropped cluster.
  thread_local AzimuthIndex index;
  thread_local std::vector<int> linked;
  index.clear();
  bool rebuild = false;
  int prev_ring = 0;
  for (size_t k = 0; k < features.size(); ++k) {
    const Feature& f = features[k];
    if (rebuild || (k > 0 && f.ring < prev_ring)) {
      index.clear();
      for (size_t c = 0; c < clusters.size(); ++c)
        if (clusters[c].parent < 0 && clusters[c].max_ring + gap >= f.ring)
          index.update(static_cast<int>(c), clusters[c], tau);
      rebuild = false;
    }
    prev_ring = f.ring;
    // eq. (2): inside the tau-padded x-y box and within ring_gap of the ring span.
    auto links = [&](const Cluster& cl) {
      return f.x >= cl.min_x - tau && f.x <= cl.max_x + tau && f.y >= cl.min_y - tau &&
             f.y <= cl.max_y + tau && f.ring >= cl.min_ring - gap;
    };
    linked.clear();
    const int b = AzimuthIndex::bin_of(f.x, f.y);
    if (b >= 0) {
      std::vector<int>& bin = index.bin(b);
      size_t kept = 0;
      for (size_t a = 0; a < bin.size(); ++a) {
        const int c = bin[a];
        const Cluster& cl = clusters[static_cast<size_t>(c)];
        if (cl.parent >= 0 || cl.max_ring + gap < f.ring) continue;  // merged, or behind
        bin[kept++] = c;
        if (links(cl)) linked.push_back(c);
      }
      bin.resize(kept);
    } else {
      // Not finite: no azimuth. Every comparison with a NaN fails, but an infinite coordinate may
      // pass against a box that reaches infinity: test every live cluster.
      for (size_t c = 0; c < clusters.size(); ++c) {
        const Cluster& cl = clusters[c];
        if (cl.parent < 0 && cl.max_ring + gap >= f.ring && links(cl))
          linked.push_back(static_cast<int>(c));
      }
    }
    int target = -1;
    float box[4] = {0, 0, 0, 0};  // the target's box before the feature
    auto link = [&](int c) {
      c = find_root(clusters, c);
      if (target < 0) {
        target = c;
        const Cluster& t = clusters[static_cast<size_t>(c)];
        box[0] = t.min_x, box[1] = t.max_x, box[2] = t.min_y, box[3] = t.max_y;
      } else if (c != target) {  // single linkage: the feature bridges two clusters
        absorb(clusters[static_cast<size_t>(target)], clusters[static_cast<size_t>(c)]);
        clusters[static_cast<size_t>(c)].parent = target;
      }
    };
    if (!linked.empty()) {
      // The lowest-numbered cluster takes the feature (the first of a test in creation order).
      const auto first = std::min_element(linked.begin(), linked.end());
      std::iter_swap(linked.begin(), first);
      for (const int c : linked) link(c);
    }
    if (f.partner >= 0) {
      const int root = find_root(clusters, labels[static_cast<size_t>(f.partner)]);
      if (clusters[static_cast<size_t>(root)].max_ring + gap < f.ring) rebuild = true;
      link(root);
    }
    if (target < 0) {
      clusters.push_back(single(f));
      target = static_cast<int>(clusters.size()) - 1;
      index.update(target, clusters.back(), tau);
    } else {
      Cluster& t = clusters[static_cast<size_t>(target)];
      absorb(t, single(f));
      if (t.min_x != box[0] || t.max_x != box[1] || t.min_y != box[2] || t.max_y != box[3])
        index.update(target, t, tau);
    }
    labels[k] = target;
  }
  for (auto& l : labels) l = find_root(clusters, l);
  if (max_extent_m <= 0.0f) return;
  // The box rule snowballs (see cluster_features in the header): oversized clusters are split into
  // their features' single-linkage components. Their features are gathered in one pass (a split
  // relabels only its own cluster's features, to new clusters).
  const size_t live = clusters.size();
  thread_local std::vector<int> slot, offsets, members, where;
  slot.assign(live, -1);
  offsets.clear();
  for (size_t c = 0; c < live; ++c) {
    const Cluster& cl = clusters[c];
    if (cl.parent < 0 &&
        (cl.max_x - cl.min_x > max_extent_m || cl.max_y - cl.min_y > max_extent_m)) {
      slot[c] = static_cast<int>(offsets.size());
      offsets.push_back(0);
    }
  }
  if (offsets.empty()) return;
  offsets.push_back(0);
  for (const int l : labels)
    if (slot[static_cast<size_t>(l)] >= 0)
      ++offsets[static_cast<size_t>(slot[static_cast<size_t>(l)]) + 1];
  for (size_t s = 1; s < offsets.size(); ++s) offsets[s] += offsets[s - 1];
  members.resize(static_cast<size_t>(offsets.back()));
  where.assign(features.size(), -1);
  for (size_t k = 0; k < labels.size(); ++k) {
    const int s = slot[static_cast<size_t>(labels[k])];
    if (s < 0) continue;
    const int at = offsets[static_cast<size_t>(s)]++;
    members[static_cast<size_t>(at)] = static_cast<int>(k);
  }
  // offsets[s] is now the end of split s's members (and the start of split s + 1's).
  int begin = 0;
  for (size_t c = 0; c < live; ++c) {
    if (slot[c] < 0) continue;
    const int end = offsets[static_cast<size_t>(slot[c])];
    const std::span<const int> mine(members.data() + begin, static_cast<size_t>(end - begin));
    for (size_t i = 0; i < mine.size(); ++i)
      where[static_cast<size_t>(mine[i])] = static_cast<int>(i);
    split_cluster(features, tau, opt.ring_gap, static_cast<int>(c), mine, where, clusters, labels);
    for (const int k : mine) where[static_cast<size_t>(k)] = -1;
    begin = end;
  }
}

void group_by_cluster(std::span<const int> labels, size_t clusters, std::vector<int>& offsets,
                      std::vector<int>& order) {
  // Counts shifted by two, so that offsets[c + 1] is cluster c's insertion cursor while the
  // features are placed and ends as the start of cluster c + 1.
  offsets.assign(clusters + 2, 0);
  for (int l : labels) ++offsets[static_cast<size_t>(l) + 2];
  for (size_t c = 2; c < offsets.size(); ++c) offsets[c] += offsets[c - 1];
  order.resize(labels.size());
  for (size_t k = 0; k < labels.size(); ++k)
    order[static_cast<size_t>(offsets[static_cast<size_t>(labels[k]) + 1]++)] = static_cast<int>(k);
  offsets.pop_back();
}

}  // namespace lidartag::detector
