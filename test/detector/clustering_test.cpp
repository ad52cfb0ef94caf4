// Stage 2: single linkage with eq. (2).
#include "lidartag/detector/clustering.hpp"

#include <gtest/gtest.h>

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
