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

// Splits cluster `c` (too large) into the single-linkage components of its features: two features
// link when both x and y differ by at most tau and their rings by at most ring_gap, or when they
// are partners (the two ends of one ring run). New clusters are appended; `c` is retired.
void split_cluster(std::span<const Feature> features, float tau, int ring_gap, int c,
                   std::vector<Cluster>& clusters, std::vector<int>& labels) {
  thread_local std::vector<int> members, parent, where, root_cluster;
  members.clear();
  for (size_t k = 0; k < labels.size(); ++k)
    if (labels[k] == c) members.push_back(static_cast<int>(k));
  const size_t m = members.size();
  parent.resize(m);
  for (size_t i = 0; i < m; ++i) parent[i] = static_cast<int>(i);
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
  // Position of each feature in `members` (features come in ring order, so do members).
  where.assign(features.size(), -1);
  for (size_t i = 0; i < m; ++i) where[static_cast<size_t>(members[i])] = static_cast<int>(i);
  for (size_t i = 0; i < m; ++i) {
    const Feature& f = features[static_cast<size_t>(members[i])];
    for (size_t j = i; j-- > 0;) {
      const Feature& g = features[static_cast<size_t>(members[j])];
      if (g.ring < f.ring - ring_gap) break;
      if (std::abs(g.x - f.x) <= tau && std::abs(g.y - f.y) <= tau)
        unite(static_cast<int>(i), static_cast<int>(j));
    }
    if (f.partner >= 0 && where[static_cast<size_t>(f.partner)] >= 0)
      unite(static_cast<int>(i), where[static_cast<size_t>(f.partner)]);
  }
  root_cluster.assign(m, -1);
  for (size_t i = 0; i < m; ++i) {
    const int r = root(static_cast<int>(i));
    const Feature& f = features[static_cast<size_t>(members[i])];
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

}  // namespace

void cluster_features(std::span<const Feature> features, float tau, float max_extent_m,
                      const ClusterOptions& opt, std::vector<Cluster>& clusters,
                      std::vector<int>& labels) {
  clusters.clear();
  labels.assign(features.size(), -1);
  // The live clusters a feature may still link to, in index order. Features come ring by ring, so
  // a cluster whose ring span ends more than ring_gap below the feature's ring is out of reach for
  // good: it is dropped from the list (the linkage loop was features x clusters). The list is
  // rebuilt when that reasoning does not hold: the rings go down, or a partner link revives a
  // dropped cluster.
  thread_local std::vector<int> active;
  active.clear();
  bool rebuild = false;
  int prev_ring = 0;
  for (size_t k = 0; k < features.size(); ++k) {
    const Feature& f = features[k];
    if (rebuild || (k > 0 && f.ring < prev_ring)) {
      active.clear();
      for (size_t c = 0; c < clusters.size(); ++c)
        if (clusters[c].parent < 0) active.push_back(static_cast<int>(c));
      rebuild = false;
    }
    prev_ring = f.ring;
    int target = -1;
    auto link = [&](int c) {
      c = find_root(clusters, c);
      if (target < 0) {
        target = c;
      } else if (c != target) {  // single linkage: the feature bridges two clusters
        absorb(clusters[static_cast<size_t>(target)], clusters[static_cast<size_t>(c)]);
        clusters[static_cast<size_t>(c)].parent = target;
      }
    };
    size_t kept = 0;
    for (size_t a = 0; a < active.size(); ++a) {
      const int c = active[a];
      const Cluster& cl = clusters[static_cast<size_t>(c)];
      if (cl.parent >= 0 || cl.max_ring + opt.ring_gap < f.ring) continue;  // merged, or behind
      active[kept++] = c;
      // eq. (2): inside the tau-padded x-y box and within one ring of the ring span.
      if (f.x >= cl.min_x - tau && f.x <= cl.max_x + tau && f.y >= cl.min_y - tau &&
          f.y <= cl.max_y + tau && f.ring >= cl.min_ring - opt.ring_gap)
        link(c);
    }
    active.resize(kept);
    if (f.partner >= 0) {
      const int root = find_root(clusters, labels[static_cast<size_t>(f.partner)]);
      if (clusters[static_cast<size_t>(root)].max_ring + opt.ring_gap < f.ring) rebuild = true;
      link(root);
    }
    if (target < 0) {
      clusters.push_back(single(f));
      target = static_cast<int>(clusters.size()) - 1;
      active.push_back(target);
    } else {
      absorb(clusters[static_cast<size_t>(target)], single(f));
    }
    labels[k] = target;
  }
  for (auto& l : labels) l = find_root(clusters, l);
  if (max_extent_m <= 0.0f) return;
  // The box rule snowballs (see cluster_features in the header): oversized clusters are split into
  // their features' single-linkage components.
  const size_t live = clusters.size();
  for (size_t c = 0; c < live; ++c) {
    const Cluster& cl = clusters[c];
    if (cl.parent < 0 && (cl.max_x - cl.min_x > max_extent_m || cl.max_y - cl.min_y > max_extent_m))
      split_cluster(features, tau, opt.ring_gap, static_cast<int>(c), clusters, labels);
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
