// Stage 3: fill-in, point-count bounds, payload boundary points eq. (5).
#include "lidartag/detector/cluster_validation.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "lidartag/detector/edge_features.hpp"
#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

struct Filled {
  Scan scan;
  std::vector<ClusterPoint> points;
  int tag_cells = 0;  // returns on the tag in the scan
};

Filled fill_tag(double distance, uint8_t white, uint8_t black) {
  Filled out;
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticScene scene;
  scene.white = white;
  scene.black = black;
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.center = Eigen::Vector3d(distance, 2, 0);
  tag.rotation = test::facing_sensor(tag.center, 45);
  scene.tags.push_back(tag);
  scene.wall_x = distance + 4;
  test::render_scene(scene, test::vlp32c(), out.scan);
  for (size_t i = 0; i < out.scan.range.size(); ++i) {
    if (!out.scan.valid(i)) continue;
    const Eigen::Vector3d p(out.scan.x[i], out.scan.y[i], out.scan.z[i]);
    const Eigen::Vector3d q = tag.rotation.transpose() * (p - tag.center);
    if (std::abs(q.x()) < 1e-3 && std::abs(q.y()) <= 0.6 && std::abs(q.z()) <= 0.6) ++out.tag_cells;
  }
  std::vector<Feature> f;
  std::vector<float> g;
  detect_edge_features(out.scan, FeatureOptions{}, 1.9f, f, g);
  std::vector<int> members;
  Cluster cl;
  cl.min_x = cl.min_y = 1e9f;
  cl.max_x = cl.max_y = -1e9f;
  cl.min_ring = 1000;
  cl.max_ring = -1;
  for (size_t k = 0; k < f.size(); ++k) {
    const Eigen::Vector3d p(f[k].x, f[k].y, f[k].z);
    if ((p - tag.center).norm() > 1.0) continue;
    members.push_back(static_cast<int>(k));
    cl.min_x = std::min(cl.min_x, f[k].x);
    cl.max_x = std::max(cl.max_x, f[k].x);
    cl.min_y = std::min(cl.min_y, f[k].y);
    cl.max_y = std::max(cl.max_y, f[k].y);
    cl.min_ring = std::min(cl.min_ring, f[k].ring);
    cl.max_ring = std::max(cl.max_ring, f[k].ring);
  }
  cl.features = static_cast<int>(members.size());
  std::vector<int> work;
  EXPECT_EQ(fill_cluster(out.scan, f, members, cl, ValidationOptions{}, 2.0f, out.points, work),
            Rejection::kNone);
  return out;
}

TEST(ClusterValidation, FillInTakesEveryTagReturnAndNothingBehind) {
  const Filled f = fill_tag(6, 220, 20);
  // All but a ring touching a vertex with a single return (no two features there).
  EXPECT_LE(static_cast<int>(f.points.size()), f.tag_cells);
  EXPECT_GE(static_cast<int>(f.points.size()), f.tag_cells - 2);
  int edges = 0;
  for (const auto& p : f.points) {
    EXPECT_LT(std::abs(p.x - 6.0f), 0.9f);
    edges += p.edge ? 1 : 0;
  }
  EXPECT_EQ(edges, 2 * rings_in(f.points));
}

TEST(ClusterValidation, TooSmallOrTooLargeClustersAreRejectedEarly) {
  Scan s;
  s.reserve(4, 1, 10);
  s.columns = 10;
  const std::vector<Feature> f(2);
  const std::vector<int> members = {0, 1};
  Cluster cl;
  cl.max_ring = 3;
  std::vector<ClusterPoint> pts;
  std::vector<int> work;
  EXPECT_EQ(fill_cluster(s, f, members, cl, ValidationOptions{}, 2.0f, pts, work),
            Rejection::kFewFeatures);
  const std::vector<Feature> f4(4);
  const std::vector<int> m4 = {0, 1, 2, 3};
  cl.max_x = 3.0f;
  EXPECT_EQ(fill_cluster(s, f4, m4, cl, ValidationOptions{}, 2.0f, pts, work),
            Rejection::kTooLarge);
}

TEST(ClusterValidation, UpperBoundHoldsForAFaceOnTag) {
  for (double d : {4.0, 8.0, 14.0}) {
    const Filled f = fill_tag(d, 220, 20);
    const double bound = max_tag_points(f.points, 1.2, 0.2 * std::numbers::pi / 180);
    EXPECT_GE(bound, static_cast<double>(f.points.size())) << d;
    EXPECT_LT(bound, 3.0 * static_cast<double>(f.points.size())) << d;
  }
}

TEST(ClusterValidation, PayloadBoundaryPointsNeedContrast) {
  const Filled tag = fill_tag(6, 220, 20);
  const int psi = 2 * (4 + 2);  // eq. (6) for tag16h5
  EXPECT_GE(count_boundary_points(tag.points, ValidationOptions{}), psi);
  const Filled flat = fill_tag(6, 120, 118);  // the same tag printed with no contrast
  EXPECT_EQ(count_boundary_points(flat.points, ValidationOptions{}), 0);
}

// eq. (5) can fire only at points with gi_ell points of their ring on both sides.
TEST(ClusterValidation, TestablePointsAreThoseWithNeighboursOnBothSidesOfTheirRing) {
  std::vector<ClusterPoint> points;
  for (int ring : {3, 4, 5})
    for (int c = 0; c < (ring == 3 ? 5 : ring == 4 ? 2 : 10); ++c) {
      ClusterPoint& p = points.emplace_back();
      p.ring = ring;
      p.col = c;
    }
  ValidationOptions o;
  EXPECT_EQ(testable_points(points, o), 3 + 0 + 8);
  o.gi_ell = 2;
  EXPECT_EQ(testable_points(points, o), 1 + 0 + 6);
  EXPECT_EQ(testable_points({}, o), 0);
}

// The tracks' boundary bound depends on what the rings crossing the cluster can show: a
// well-sampled cluster keeps track_boundary_scale's bound, a sparse one (few returns per ring)
// asks for one transition per track_testable_per_transition testable points, never below psi / 4.
TEST(ClusterValidation, TheTracksBoundaryBoundFollowsTheRingsCrossingTheCluster) {
  const int psi = 12, track = 9;  // tag16h5: 2 (d + 2), and 0.75 of it
  const ValidationOptions o;
  EXPECT_EQ(track_boundary_bound(500, 10, psi, track, o), track);
  // 10 rings of 5 returns: 3 testable each, one transition per 8 of them.
  EXPECT_EQ(track_boundary_bound(30, 10, psi, track, o), 4);
  EXPECT_EQ(track_boundary_bound(0, 10, psi, track, o), 3);
  EXPECT_EQ(track_boundary_bound(-4, 10, psi, track, o), 3);
  // A VLP-32C's 1.2 m tag at 6 m keeps the bound, and shows more transitions than it.
  const Filled near = fill_tag(6, 220, 20);
  EXPECT_EQ(
      track_boundary_bound(testable_points(near.points, {}), rings_in(near.points), psi, track, o),
      track);
  EXPECT_GE(count_boundary_points(near.points, {}), track);
  // Six rings of five returns across a turned tag at the far edge (white, black, black, white,
  // white): one transition each, below the well-sampled bound, at the sparse one.
  std::vector<ClusterPoint> far;
  for (int ring = 0; ring < 6; ++ring)
    for (const float intensity : {220.0f, 20.0f, 20.0f, 220.0f, 220.0f}) {
      ClusterPoint& p = far.emplace_back();
      p.ring = ring;
      p.intensity = intensity;
    }
  const int shown = count_boundary_points(far, {});
  EXPECT_EQ(shown, 6);
  EXPECT_LT(shown, track);
  const int bound = track_boundary_bound(testable_points(far, {}), rings_in(far), psi, track, o);
  EXPECT_EQ(bound, 3);
  EXPECT_GE(shown, bound);
}

// The far edge's sparse rotations: 38 testable points on 10 rings (a VLP-32C's 1.2 m tag at 28 m
// and 45 degrees) showing 5 transitions passed one per 8 testable points, not one per 6 (the
// rate before 2026-12-05, which dropped those rotations: bench_tracker --cell vlp32c:28:45
// --trace); a sparser rate asks for fewer.
TEST(ClusterValidation, TheTracksBoundaryBoundAsksOneTransitionPerTestablePointsOfItsRate) {
  const int psi = 12, track = 9;
  ValidationOptions o;
  EXPECT_EQ(track_boundary_bound(38, 10, psi, track, o), 5);
  o.track_testable_per_transition = 6.0f;
  EXPECT_EQ(track_boundary_bound(38, 10, psi, track, o), 7);
  o.track_testable_per_transition = 100.0f;
  EXPECT_EQ(track_boundary_bound(38, 10, psi, track, o), 3);  // never below psi / 4
}

// Few rings with many returns each (a VLP-16's tag at 10 m and 45 degrees: 5 rings of 20 returns)
// show at most about track_transitions_per_ring transitions per ring, however many of their points
// are testable: the bound asks no more than that; 0 turns the cap off.
TEST(ClusterValidation, TheTracksBoundaryBoundAsksAtMostTransitionsPerRingCrossingTheCluster) {
  const int psi = 12, track = 9;
  ValidationOptions o;
  EXPECT_EQ(track_boundary_bound(90, 5, psi, track, o), 8);   // ceil(1.5 * 5)
  EXPECT_EQ(track_boundary_bound(90, 4, psi, track, o), 6);   // ceil(1.5 * 4)
  EXPECT_EQ(track_boundary_bound(90, 2, psi, track, o), 3);   // never below psi / 4
  EXPECT_EQ(track_boundary_bound(90, 10, psi, track, o), 9);  // many rings: the track bound
  o.track_transitions_per_ring = 0.0f;
  EXPECT_EQ(track_boundary_bound(90, 5, psi, track, o), track);
}

// The looser far-edge bound still asks for transitions a blank board never shows: a uniform
// 1.2 m board turned 45 degrees at 20 m (VLP-32C) has no payload boundary point against its bound
// of at least psi / 4.
TEST(ClusterValidation, ABlankBoardStaysBelowTheTracksBoundaryBound) {
  const int psi = 12, track = 9;
  const Filled blank = fill_tag(20, 200, 200);
  ASSERT_GT(testable_points(blank.points, {}), 0);
  const int bound = track_boundary_bound(testable_points(blank.points, {}), rings_in(blank.points),
                                         psi, track, {});
  EXPECT_GE(bound, (psi + 3) / 4);
  EXPECT_LT(count_boundary_points(blank.points, {}), bound);
}

TEST(ClusterValidation, NarrowRingsAboveAndBelowAreTrimmed) {
  // Rings 0-2: a 5 cm post; 3-6: the 1 m board, ring 5 crossing it narrowly at a gap; 7: a lamp.
  std::vector<ClusterPoint> pts;
  auto ring = [&](int r, float width) {
    for (float y = 0.0f; y <= width + 1e-6f; y += 0.025f) {
      ClusterPoint p;
      p.x = 5.0f;
      p.y = y;
      p.z = 0.1f * static_cast<float>(r);
      p.ring = r;
      pts.push_back(p);
    }
  };
  for (int r = 0; r < 3; ++r) ring(r, 0.05f);
  for (int r = 3; r < 7; ++r) ring(r, r == 5 ? 0.05f : 1.0f);
  ring(7, 0.1f);
  const size_t before = pts.size();
  const size_t dropped = trim_narrow_rings(pts, 0.3f);
  EXPECT_EQ(dropped, 3u * 3u + 5u);
  EXPECT_EQ(pts.size(), before - dropped);
  EXPECT_EQ(pts.front().ring, 3);
  EXPECT_EQ(pts.back().ring, 6);
  EXPECT_EQ(rings_in(pts), 4);  // the narrow ring inside the board stays
  EXPECT_EQ(trim_narrow_rings(pts, 0.0f), 0u);
}

}  // namespace
}  // namespace lidartag::detector
