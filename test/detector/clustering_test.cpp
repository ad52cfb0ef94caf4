// Stage 2: single linkage with eq. (linkage).
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
  cluster_features(f, 0.42f, ClusterOptions{}, cs, labels);
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
  cluster_features(f, 0.42f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 3);  // 0.5 m apart > tau; ring 6 is 3 rings away
  cluster_features(f, 0.6f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
  ClusterOptions wide;
  wide.ring_gap = 3;
  cluster_features(f, 0.6f, wide, cs, labels);
  EXPECT_EQ(live(cs), 1);
}

TEST(Clustering, AFeatureBridgingTwoClustersMergesThem) {
  const std::vector<Feature> f = {at(5, 0, 3), at(5, 0.8f, 3), at(5, 0.4f, 4)};
  std::vector<Cluster> cs;
  std::vector<int> labels;
  cluster_features(f, 0.42f, ClusterOptions{}, cs, labels);
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
  cluster_features(f, 0.42f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 1);
  for (auto& p : f) p.partner = -1;
  cluster_features(f, 0.42f, ClusterOptions{}, cs, labels);
  EXPECT_EQ(live(cs), 2);
}

}  // namespace
}  // namespace lidartag::detector
