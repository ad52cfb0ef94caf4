#include "lidartag/detector/clustering.hpp"

#include <algorithm>

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

}  // namespace

void cluster_features(std::span<const Feature> features, float tau, const ClusterOptions& opt,
                      std::vector<Cluster>& clusters, std::vector<int>& labels) {
  clusters.clear();
  labels.assign(features.size(), -1);
  for (size_t k = 0; k < features.size(); ++k) {
    const Feature& f = features[k];
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
    for (size_t c = 0; c < clusters.size(); ++c) {
      const Cluster& cl = clusters[c];
      if (cl.parent >= 0) continue;
      // eq. (linkage): inside the tau-padded x-y box and within one ring of the ring span.
      if (f.x >= cl.min_x - tau && f.x <= cl.max_x + tau && f.y >= cl.min_y - tau &&
          f.y <= cl.max_y + tau && f.ring >= cl.min_ring - opt.ring_gap &&
          f.ring <= cl.max_ring + opt.ring_gap)
        link(static_cast<int>(c));
    }
    if (f.partner >= 0) link(labels[static_cast<size_t>(f.partner)]);
    if (target < 0) {
      Cluster n;
      n.min_x = n.max_x = f.x;
      n.min_y = n.max_y = f.y;
      n.min_ring = n.max_ring = f.ring;
      clusters.push_back(n);
      target = static_cast<int>(clusters.size()) - 1;
    } else {
      Cluster one;
      one.min_x = one.max_x = f.x;
      one.min_y = one.max_y = f.y;
      one.min_ring = one.max_ring = f.ring;
      one.features = 0;
      absorb(clusters[static_cast<size_t>(target)], one);
    }
    clusters[static_cast<size_t>(target)].features += 1;
    labels[k] = target;
  }
  for (auto& l : labels) l = find_root(clusters, l);
}

}  // namespace lidartag::detector
