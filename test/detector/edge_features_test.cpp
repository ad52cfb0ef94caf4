// Stage 1: distance-gradient features, eq. (1), and the one-edge-among-n+1 rule.
#include "lidartag/detector/edge_features.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

// One ring, a partial rotation, ranges along +x direction spread in azimuth.
Scan ring_of(const std::vector<float>& ranges) {
  Scan s;
  const int n = static_cast<int>(ranges.size());
  s.reserve(1, 1, n);
  s.columns = n;
  for (int c = 0; c < n; ++c) {
    s.column_azimuth_deg[static_cast<size_t>(c)] = 0.2f * static_cast<float>(c);  // partial
    const size_t i = s.at(0, 0, c);
    const float r = ranges[static_cast<size_t>(c)];
    const double a = 0.2 * c * 3.14159265358979 / 180.0;
    s.range[i] = r;
    s.x[i] = r * static_cast<float>(std::cos(a));
    s.y[i] = -r * static_cast<float>(std::sin(a));
    s.z[i] = 0.0f;
  }
  return s;
}

TEST(EdgeFeatures, MarksTheNearSideOfEachJump) {
  std::vector<float> r(40, 10.0f);
  for (int c = 15; c < 25; ++c) r[static_cast<size_t>(c)] = 6.0f;  // an object 4 m in front
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[0].col, 15);
  EXPECT_EQ(f[0].side, -1);
  EXPECT_EQ(f[1].col, 24);
  EXPECT_EQ(f[1].side, 1);
  EXPECT_FLOAT_EQ(f[0].range, 6.0f);
}

TEST(EdgeFeatures, StepsBelowZetaAreNotEdges) {
  std::vector<float> r(40, 10.0f);
  for (int c = 15; c < 25; ++c) r[static_cast<size_t>(c)] = 9.7f;
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
  EXPECT_TRUE(f.empty());
  FeatureOptions o;
  o.zeta_m = 0.2f;
  detect_edge_features(s, o, 0.0f, f, g);
  EXPECT_EQ(f.size(), 2u);
}

TEST(EdgeFeatures, RunsOfEdgesAreNotFeatures) {
  // Vegetation: alternating near and far returns make edges in consecutive points.
  // Two near returns, one far, repeated: every near return is an edge point.
  std::vector<float> r(40, 10.0f);
  for (int c : {10, 11, 13, 14, 16, 17}) r[static_cast<size_t>(c)] = 5.0f;
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
  ASSERT_EQ(f.size(), 2u);  // only the outer ends have a window of n+1 = 3 with one edge
  EXPECT_EQ(f[0].col, 10);
  EXPECT_EQ(f[1].col, 17);
  FeatureOptions keep;
  keep.n = 0;  // every edge point is a feature
  detect_edge_features(s, keep, 0.0f, f, g);
  EXPECT_EQ(f.size(), 6u);
}

TEST(EdgeFeatures, MissingNeighboursCountAsFarAndShortRunsArePaired) {
  std::vector<float> r(40, 0.0f);  // sky
  for (int c = 10; c < 30; ++c) r[static_cast<size_t>(c)] = 5.0f;
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  const FeatureOptions o;
  // The run is 19 * 0.2 deg * 5 m = 0.33 m long.
  detect_edge_features(s, o, 2.0f, f, g);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[1].partner, 0);
  detect_edge_features(s, o, 0.1f, f, g);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[1].partner, -1);
}

TEST(EdgeFeatures, ATagInAFullRotationHasTwoFeaturesPerRingAcrossTheCut) {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.center = Eigen::Vector3d(6, 0, 0);  // straddles azimuth 0, the first column
  tag.rotation = test::facing_sensor(tag.center, 0);
  scene.tags.push_back(tag);
  scene.floor = false;
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  ASSERT_TRUE(rotation_wraps(s));
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 2.0f, f, g);
  int on_tag = 0, paired = 0;
  for (const auto& x : f)
    if (std::abs(x.x - 6.0f) < 0.05f) {
      ++on_tag;
      EXPECT_LT(std::abs(x.y), 0.62f);
      paired += x.partner >= 0 ? 1 : 0;
    }
  // Rings between -5.7 and 5.7 degrees cross the 1.2 m tag at 6 m: two features each.
  EXPECT_GE(on_tag, 2 * 20);
  EXPECT_EQ(paired * 2, on_tag);
}

TEST(EdgeFeatures, ShortDropoutsOnASurfaceAreNotEdges) {
  std::vector<float> r(60, 10.0f);                                 // a wall
  r[10] = 0.0f;                                                    // one lost beam
  for (int c = 30; c < 33; ++c) r[static_cast<size_t>(c)] = 0.0f;  // three in a row
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
  EXPECT_TRUE(f.empty());
  // Every missing return is a jump without the gap rule: each dropout makes two edges.
  FeatureOptions no_gap;
  no_gap.max_gap = 0;
  detect_edge_features(s, no_gap, 0.0f, f, g);
  EXPECT_EQ(f.size(), 4u);
}

TEST(EdgeFeatures, LongGapsAndRealStepsAcrossADropoutStayEdges) {
  std::vector<float> r(60, 0.0f);                                  // sky
  for (int c = 10; c < 25; ++c) r[static_cast<size_t>(c)] = 5.0f;  // a board
  for (int c = 27; c < 50; ++c) r[static_cast<size_t>(c)] = 9.0f;  // 4 m behind, after 2 lost
  const Scan s = ring_of(r);
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].col, 10);  // against the sky (more than max_gap columns without a return)
  EXPECT_EQ(f[1].col, 24);  // the step to the background behind the dropout
  EXPECT_EQ(f[1].side, 1);
  EXPECT_EQ(f[2].col, 49);  // the background ends against the sky
}

// The interior of a ring is tested in blocks of columns: an object starting and ending at any
// column of a block (and at the ends of the ring) is found the same way.
TEST(EdgeFeatures, EdgesAreFoundWhereverTheyFallInARing) {
  for (int start = 1; start < 40; ++start) {
    std::vector<float> r(48, 10.0f);
    for (int c = start; c < start + 7 && c < 47; ++c) r[static_cast<size_t>(c)] = 6.0f;
    const int end = std::min(start + 6, 46);
    const Scan s = ring_of(r);
    std::vector<Feature> f;
    std::vector<float> g;
    detect_edge_features(s, FeatureOptions{}, 0.0f, f, g);
    ASSERT_EQ(f.size(), 2u) << "object at columns " << start << "-" << end;
    EXPECT_EQ(f[0].col, start);
    EXPECT_EQ(f[0].side, -1);
    EXPECT_EQ(f[1].col, end);
    EXPECT_EQ(f[1].side, 1);
  }
}

// Inside a ring the neighbour behind a dropout is found from the window's returns at once, near
// the ends column by column: a dropout of any length next to an object at any column gives the
// same features as the rule says (gaps up to max_gap are bridged, longer ones are sky).
TEST(EdgeFeatures, DropoutsAreBridgedTheSameWayAnywhereInARing) {
  const FeatureOptions opt;
  for (int gap = 1; gap <= opt.max_gap + 2; ++gap) {
    for (int start = 1; start < 30; ++start) {
      std::vector<float> r(40, 10.0f);  // a wall; an object 4 m in front, then a dropout
      const int end = std::min(start + 4, 39);
      for (int c = start; c <= end; ++c) r[static_cast<size_t>(c)] = 6.0f;
      for (int c = end + 1; c <= end + gap && c < 40; ++c) r[static_cast<size_t>(c)] = 0.0f;
      const Scan s = ring_of(r);
      std::vector<Feature> f;
      std::vector<float> g;
      detect_edge_features(s, opt, 0.0f, f, g);
      // The object's right end is an edge whether the wall behind the dropout is reached (a
      // range step of 4 m) or not (no return: infinitely far).
      const auto has = [&](int col, int side) {
        return std::any_of(f.begin(), f.end(),
                           [&](const Feature& e) { return e.col == col && e.side == side; });
      };
      EXPECT_TRUE(has(start, -1)) << "object at " << start << ", gap " << gap;
      EXPECT_TRUE(has(end, 1)) << "object at " << start << ", gap " << gap;
      // Beyond max_gap the wall after the dropout starts against the sky: its first column is an
      // edge too; a bridged dropout leaves the wall's columns quiet.
      const int wall = end + gap + 1;
      if (wall < 39) {
        EXPECT_EQ(has(wall, -1), gap > opt.max_gap) << "object at " << start << ", gap " << gap;
      }
    }
  }
}

}  // namespace
}  // namespace lidartag::detector
