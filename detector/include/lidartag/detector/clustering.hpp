// Stage 2 (paper Sec. IV-B): single-linkage clustering of the features, eq. (2) [linkage].
#pragma once

#include <span>
#include <vector>

#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

struct ClusterOptions {
  // tau of eq. (2) = linkage_scale * t_max * sqrt(2) / 4, where t_max is the largest
  // configured tag size. Default 1 (the paper's). A tag needs tau of clearance from other objects.
  float linkage_scale = 1.0f;
  // A feature joins a cluster whose rings span [r_min - ring_gap, r_max + ring_gap]. Default 1 (the
  // paper's); 2 tolerates one ring without returns on the tag.
  int ring_gap = 1;
};

// A cluster: the x-y box and ring span of its features (the paper's b_1..b_4, r_min, r_max).
struct Cluster {
  float min_x = 0, max_x = 0, min_y = 0, max_y = 0;
  int min_ring = 0, max_ring = 0;
  int features = 0;
  int parent = -1;  // -1 for a live cluster; else the cluster it was merged into
};

// Clusters `features` (in ring order, as detect_edge_features emits them) with box padding `tau`
// metres, eq. (2). On return `clusters` holds every cluster created, merged ones with parent >= 0,
// and labels[i] is the live cluster of feature i. True single linkage: a feature that links to
// several clusters merges them; a feature also joins the cluster of its `partner` (the other side
// of its ring run), so that a tag mounted as a square, whose sides are a full tag apart, is one
// cluster.
// Clusters whose x-y box is larger than `max_extent_m` are split into the single-linkage
// components of their features (x and y within tau, rings within ring_gap, or ring-run partners).
// The paper's box rule snowballs: two merged clusters span the space between them, so every
// feature there joins, and a tag near a chain of clutter ends up in one room-sized cluster
// rejected as too large. The detector passes 1.25 x the largest tag's diagonal; 0: no split.
void cluster_features(std::span<const Feature> features, float tau, float max_extent_m,
                      const ClusterOptions& opt, std::vector<Cluster>& clusters,
                      std::vector<int>& labels);

// The features grouped by cluster (a counting sort of `labels`, stable): the features of cluster
// c are order[offsets[c]], ..., order[offsets[c + 1] - 1], in their original order. `offsets`
// gets `clusters` + 1 entries.
void group_by_cluster(std::span<const int> labels, size_t clusters, std::vector<int>& offsets,
                      std::vector<int>& order);

}  // namespace lidartag::detector
