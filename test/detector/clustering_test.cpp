// Stage 2: single linkage with eq. (2).
#include "lidartag/detector/clustering.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace lidartag::detector {
namespace {

Feature at(float x, float y, int ring, int partner = -1) {
  Feature f;
  f.x = x;
  f.y = y;
  f.ring = ring;
  f.partner = partner;
  return f;
}

int live(const std::vector<Cluster>& cs) {
  int n = 0;
  for (const auto& c : cs) n += c.parent < 0 ? 1 : 0;
  return n;
}

TEST(Clustering, NearbyFeaturesOnAdjacentRingsLink) {
  const std::vector<Feature> f = {at(5, 0, 3), at(5, 0.3f, 4), at(5, 0.5f, 5), at(9, 4, 3)};
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
  EXPECT_EQ(labels[0], labels[1]);
  EXPECT_EQ(labels[1], labels[2]);
  EXPECT_NE(labels[0], labels[3]);
  const Cluster& c = cs[static_cast<size_t>(labels[0])];
  EXPECT_EQ(c.min_ring, 3);
  EXPECT_EQ(c.max_ring, 5);
  EXPECT_FLOAT_EQ(c.max_y, 0.5f);
  EXPECT_EQ(c.features, 3);
}

TEST(Clustering, TauAndRingGapBoundTheLinkage) {
  const std::vector<Feature> f = {at(5, 0, 3), at(5, 0.5f, 3), at(5, 0, 6)};
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 3);  // 0.5 m apart > tau; ring 6 is 3 rings away
  cluster_features(f, 0.6f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
  ClusterOptions wide;
  wide.ring_gap = 3;
  cluster_features(f, 0.6f, 0.0f, wide, cs, labels);
  EXPECT_EQ(live(cs), 1);
}

TEST(Clustering, AFeatureBridgingTwoClustersMergesThem) {
  const std::vector<Feature> f = {at(5, 0, 3), at(5, 0.8f, 3), at(5, 0.4f, 4)};
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 1);
  EXPECT_EQ(labels[0], labels[1]);
  EXPECT_EQ(labels[0], labels[2]);
  EXPECT_FLOAT_EQ(cs[static_cast<size_t>(labels[0])].max_y, 0.8f);
}

TEST(Clustering, PartnersJoinAcrossATagWidth) {
  // A square-mounted tag: left and right sides 1.2 m apart, one pair per ring.
  std::vector<Feature> f;
  for (int ring = 0; ring < 4; ++ring) {
    f.push_back(at(6, -0.6f, ring));
    f.push_back(at(6, 0.6f, ring, static_cast<int>(f.size()) - 1));
  }
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 1);
  for (auto& p : f) p.partner = -1;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
}

// A tag (two features per ring, partners) and a chain of clutter whose first feature falls inside
// the tag's padded box without being near any of its features: the box rule merges them into one
// oversized cluster; the split keeps the tag whole and apart.
TEST(Clustering, OversizedClustersSplitIntoTheirComponents) {
  std::vector<Feature> f;
  for (int ring = 5; ring <= 10; ++ring) {
    f.push_back(at(6.0f, 0.5f, ring));
    f.push_back(at(6.0f, -0.5f, ring, static_cast<int>(f.size()) - 1));
  }
  const size_t tag_end = f.size();
  for (int k = 0; k < 12; ++k) f.push_back(at(6.0f + 0.3f * static_cast<float>(k), 0.0f, 11));
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.35f, 0.0f, ClusterOptions{}, cs, labels);  // the paper's rule alone
  EXPECT_EQ(live(cs), 1);
  cluster_features(f, 0.35f, 2.1f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
  for (size_t k = 1; k < tag_end; ++k) EXPECT_EQ(labels[k], labels[0]);
  for (size_t k = tag_end; k < f.size(); ++k) EXPECT_NE(labels[k], labels[0]);
  const Cluster& tag = cs[static_cast<size_t>(labels[0])];
  EXPECT_LT(tag.parent, 0);
  EXPECT_EQ(tag.features, static_cast<int>(tag_end));
  EXPECT_FLOAT_EQ(tag.min_y, -0.5f);
  EXPECT_FLOAT_EQ(tag.max_x, 6.0f);
  EXPECT_EQ(tag.min_ring, 5);
  EXPECT_EQ(tag.max_ring, 10);
}

// Features come ring by ring, so clusters whose rings ended more than ring_gap below are no longer
// tested; a partner link that reaches such a cluster brings it back: later features near its
// (grown) box still join it.
TEST(Clustering, APartnerLinkKeepsAnOldClusterReachable) {
  std::vector<Feature> f = {at(5, 0, 0), at(5, 0, 5, 0), at(5, 0.1f, 6)};
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 1);
  EXPECT_EQ(labels[1], labels[0]);
  EXPECT_EQ(labels[2], labels[0]);
  EXPECT_EQ(cs[static_cast<size_t>(labels[0])].max_ring, 6);
  f[1].partner = -1;  // without the link: three rings apart, three clusters
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
  EXPECT_NE(labels[1], labels[0]);
  EXPECT_EQ(labels[2], labels[1]);
}

// Eq. (2) as the header states it, without any index: each feature is tested against every live
// cluster, in the order the clusters were created; the first it links to takes the feature and
// absorbs the others; then its partner's cluster. The reference for cluster_features' output.
int reference_root(std::vector<Cluster>& cs, int i) {
  while (cs[static_cast<size_t>(i)].parent >= 0) {
    const int p = cs[static_cast<size_t>(i)].parent;
    const int gp = cs[static_cast<size_t>(p)].parent;
    if (gp >= 0) cs[static_cast<size_t>(i)].parent = gp;
    i = p;
  }
  return i;
}

void reference_absorb(Cluster& into, const Cluster& from) {
  into.min_x = std::min(into.min_x, from.min_x);
  into.max_x = std::max(into.max_x, from.max_x);
  into.min_y = std::min(into.min_y, from.min_y);
  into.max_y = std::max(into.max_y, from.max_y);
  into.min_ring = std::min(into.min_ring, from.min_ring);
  into.max_ring = std::max(into.max_ring, from.max_ring);
  into.features += from.features;
}

void reference_clustering(const std::vector<Feature>& features, float tau, int gap,
                          float max_extent, std::vector<Cluster>& cs, std::vector<int>& labels) {
  cs.clear();
  labels.assign(features.size(), -1);
  for (size_t k = 0; k < features.size(); ++k) {
    const Feature& f = features[k];
    Cluster one;
    one.min_x = one.max_x = f.x;
    one.min_y = one.max_y = f.y;
    one.min_ring = one.max_ring = f.ring;
    one.features = 1;
    int target = -1;
    auto link = [&](int c) {
      c = reference_root(cs, c);
      if (target < 0) {
        target = c;
      } else if (c != target) {
        reference_absorb(cs[static_cast<size_t>(target)], cs[static_cast<size_t>(c)]);
        cs[static_cast<size_t>(c)].parent = target;
      }
    };
    for (size_t c = 0; c < cs.size(); ++c) {
      const Cluster& cl = cs[c];
      if (cl.parent < 0 && f.ring <= cl.max_ring + gap && f.ring >= cl.min_ring - gap &&
          f.x >= cl.min_x - tau && f.x <= cl.max_x + tau && f.y >= cl.min_y - tau &&
          f.y <= cl.max_y + tau)
        link(static_cast<int>(c));
    }
    if (f.partner >= 0) link(labels[static_cast<size_t>(f.partner)]);
    if (target < 0) {
      cs.push_back(one);
      target = static_cast<int>(cs.size()) - 1;
    } else {
      reference_absorb(cs[static_cast<size_t>(target)], one);
    }
    labels[k] = target;
  }
  for (auto& l : labels) l = reference_root(cs, l);
  if (max_extent <= 0.0f) return;
  // The split of oversized clusters, feature pair by feature pair: two features link when x and y
  // are within tau and the earlier one is reached scanning back from the later one before a ring
  // more than ring_gap below it; partners link.
  const size_t live = cs.size();
  for (size_t c = 0; c < live; ++c) {
    if (cs[c].parent >= 0 ||
        (cs[c].max_x - cs[c].min_x <= max_extent && cs[c].max_y - cs[c].min_y <= max_extent))
      continue;
    std::vector<size_t> members;
    for (size_t k = 0; k < labels.size(); ++k)
      if (labels[k] == static_cast<int>(c)) members.push_back(k);
    std::vector<size_t> component(members.size());
    for (size_t i = 0; i < members.size(); ++i) component[i] = i;
    auto join = [&](size_t a, size_t b) {  // relabel the larger component as the smaller
      const size_t from = std::max(component[a], component[b]);
      const size_t to = std::min(component[a], component[b]);
      for (auto& x : component)
        if (x == from) x = to;
    };
    for (size_t i = 0; i < members.size(); ++i) {
      const Feature& f = features[members[i]];
      for (size_t j = i; j-- > 0;) {
        const Feature& g = features[members[j]];
        if (g.ring < f.ring - gap) break;
        if (std::abs(g.x - f.x) <= tau && std::abs(g.y - f.y) <= tau) join(i, j);
      }
      for (size_t j = 0; j < members.size(); ++j)
        if (f.partner >= 0 && members[j] == static_cast<size_t>(f.partner)) join(i, j);
    }
    std::vector<int> cluster_of(members.size(), -1);
    int first_cluster = -1;  // the retired cluster's parent
    for (size_t i = 0; i < members.size(); ++i) {
      const Feature& f = features[members[i]];
      Cluster one;
      one.min_x = one.max_x = f.x;
      one.min_y = one.max_y = f.y;
      one.min_ring = one.max_ring = f.ring;
      one.features = 1;
      int& to = cluster_of[component[i]];
      if (to < 0) {
        cs.push_back(one);
        to = static_cast<int>(cs.size()) - 1;
      } else {
        reference_absorb(cs[static_cast<size_t>(to)], one);
      }
      labels[members[i]] = to;
      if (i == 0) first_cluster = to;
    }
    cs[c].parent = first_cluster;
  }
}

// Random scenes as a spinning sensor sees them: objects (walls, poles, boards) at 0.3-80 m around
// the origin, some straddling it, cut by each ring into features in column order, partners
// between the ends of short runs (and, rarely, across rings); rings ascending, or in two passes.
std::vector<Feature> random_features(std::mt19937& gen, bool two_passes) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  struct Object {
    float cx, cy, dx, dy;
    int ring0, ring1;
  };
  std::vector<Object> objects(6 + gen() % 60);
  for (auto& o : objects) {
    const float r = 0.3f + 80.0f * u(gen) * u(gen);
    const float a = 2.0f * std::numbers::pi_v<float> * u(gen);
    o.cx = r * std::cos(a);
    o.cy = r * std::sin(a);
    o.dx = 4.0f * (u(gen) - 0.5f) * (u(gen) < 0.2f ? 8.0f : 1.0f);
    o.dy = 4.0f * (u(gen) - 0.5f) * (u(gen) < 0.2f ? 8.0f : 1.0f);
    o.ring0 = static_cast<int>(gen() % 40);
    o.ring1 = o.ring0 + static_cast<int>(gen() % 12);
  }
  if (u(gen) < 0.3f) objects.push_back({0.0f, 0.0f, 0.6f, 0.0f, 0, 40});  // at the origin
  std::vector<Feature> f;
  const int passes = two_passes ? 2 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    const int ring_begin = pass == 0 ? 0 : static_cast<int>(gen() % 30);
    for (int ring = ring_begin; ring < 52; ++ring) {
      const size_t first = f.size();
      for (const auto& o : objects) {
        if (ring < o.ring0 || ring > o.ring1 || u(gen) < 0.1f) continue;
        const int n = 1 + static_cast<int>(gen() % 4);
        for (int i = 0; i < n; ++i) {
          const float t = u(gen);
          Feature e;
          e.ring = ring;
          e.x = o.cx + t * o.dx + 0.05f * (u(gen) - 0.5f);
          e.y = o.cy + t * o.dy + 0.05f * (u(gen) - 0.5f);
          f.push_back(e);
        }
      }
      for (int i = static_cast<int>(gen() % 6); i > 0; --i) {  // stray returns
        Feature e;
        e.ring = ring;
        e.x = 100.0f * (u(gen) - 0.5f);
        e.y = 100.0f * (u(gen) - 0.5f);
        f.push_back(e);
      }
      // Column order: by azimuth.
      std::sort(f.begin() + static_cast<std::ptrdiff_t>(first), f.end(),
                [](const Feature& a, const Feature& b) {
                  return std::atan2(a.y, a.x) < std::atan2(b.y, b.x);
                });
      for (size_t k = first + 1; k < f.size(); ++k)
        if (u(gen) < 0.3f)
          f[k].partner = static_cast<int>(k - 1 - gen() % std::min<size_t>(3, k - first));
      if (f.size() > first && first > 0 && u(gen) < 0.05f)  // a partner rings below
        f[f.size() - 1].partner = static_cast<int>(gen() % first);
    }
  }
  return f;
}

// The bookkeeping that makes the linkage and the split fast (which clusters a feature is tested
// against, which features of a split cluster are compared) changes nothing: every cluster (merged
// and split ones too, with their parents) and every label are those of the rules applied to every
// live cluster and every pair of features.
TEST(Clustering, OutputIsThatOfTestingEveryLiveCluster) {
  std::mt19937 gen(2026);
  std::vector<Cluster> cs, ref;
  std::vector<int> labels, ref_labels;
  for (int trial = 0; trial < 300; ++trial) {
    SCOPED_TRACE(trial);
    const std::vector<Feature> f = random_features(gen, trial % 3 == 2);
    const float tau = 0.05f + 1.2f * static_cast<float>(gen() % 1000) / 1000.0f;
    ClusterOptions opt;
    opt.ring_gap = 1 + static_cast<int>(gen() % 3);
    // Oversized clusters split (the detector's 1.25 x a diagonal) or not.
    const float max_extent = trial % 4 == 3 ? 0.0f : 1.25f * std::sqrt(8.0f) * tau;
    cluster_features(f, tau, max_extent, opt, cs, labels);
    reference_clustering(f, tau, opt.ring_gap, max_extent, ref, ref_labels);
    ASSERT_EQ(labels, ref_labels);
    ASSERT_EQ(cs.size(), ref.size());
    for (size_t c = 0; c < cs.size(); ++c) {
      SCOPED_TRACE(c);
      ASSERT_EQ(cs[c].min_x, ref[c].min_x);
      ASSERT_EQ(cs[c].max_x, ref[c].max_x);
      ASSERT_EQ(cs[c].min_y, ref[c].min_y);
      ASSERT_EQ(cs[c].max_y, ref[c].max_y);
      ASSERT_EQ(cs[c].min_ring, ref[c].min_ring);
      ASSERT_EQ(cs[c].max_ring, ref[c].max_ring);
      ASSERT_EQ(cs[c].features, ref[c].features);
      ASSERT_EQ(cs[c].parent, ref[c].parent);
    }
  }
}

// Features that are not finite link as the comparisons of eq. (2) say: one with a NaN to nothing,
// one at infinity to a box that reaches infinity; the others are not disturbed.
TEST(Clustering, NonFiniteFeaturesLinkAsTheComparisonsSay) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<Feature> f = {at(5, 0, 3),    at(nan, 0, 3),    at(inf, 0, 3), at(5, 0.3f, 4),
                                  at(0, nan, 4),  at(5, 0.5f, 5),   at(inf, 0, 4), at(nan, nan, 5),
                                  at(-inf, 1, 5), at(-inf, 1.2f, 6)};
  std::vector<Cluster> cs, ref;
  std::vector<int> labels, ref_labels;
  cluster_features(f, 0.42f, 0.0f, ClusterOptions{}, cs, labels);
  reference_clustering(f, 0.42f, 1, 0.0f, ref, ref_labels);
  EXPECT_EQ(labels, ref_labels);
  EXPECT_EQ(live(cs), 6);
  EXPECT_EQ(labels[0], labels[3]);
  EXPECT_EQ(labels[0], labels[5]);
  EXPECT_EQ(labels[2], labels[6]);  // both at +infinity, adjacent rings
  EXPECT_EQ(labels[8], labels[9]);  // both at -infinity, y within tau
  EXPECT_NE(labels[1], labels[0]);
  EXPECT_NE(labels[4], labels[0]);
  EXPECT_NE(labels[7], labels[0]);
  // A NaN feature brought into an oversized cluster by its partner: the split keeps it there.
  std::vector<Feature> chain;
  for (int k = 0; k < 12; ++k) chain.push_back(at(6.0f + 0.3f * static_cast<float>(k), 0.0f, 3));
  chain.push_back(at(nan, 0, 3, 0));
  chain.push_back(at(9.0f, 0.1f, 4));
  cluster_features(chain, 0.35f, 1.0f, ClusterOptions{}, cs, labels);
  reference_clustering(chain, 0.35f, 1, 1.0f, ref, ref_labels);
  EXPECT_EQ(labels, ref_labels);
  EXPECT_EQ(labels[12], labels[0]);
}

TEST(Clustering, FeaturesGroupedByClusterInTheirOrder) {
  const std::vector<int> labels = {2, 0, 2, 1, 0, 2};
  std::vector<int> offsets, order;
  group_by_cluster(labels, 4, offsets, order);
  EXPECT_EQ(offsets, (std::vector<int>{0, 2, 3, 6, 6}));  // cluster 3 has no features
  EXPECT_EQ(order, (std::vector<int>{1, 4, 3, 0, 2, 5}));
  group_by_cluster({}, 2, offsets, order);
  EXPECT_EQ(offsets, (std::vector<int>{0, 0, 0}));
  EXPECT_TRUE(order.empty());
}

}  // namespace
}  // namespace lidartag::detector
