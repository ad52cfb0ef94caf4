// Stage 4: outline, edge lines and intersections, for diamond and square mounts.
#include "lidartag/detector/corners.hpp"

#include <gtest/gtest.h>

#include "lidartag/detector/cluster_validation.hpp"
#include "lidartag/detector/edge_features.hpp"
#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

// The tag's returns, ring by ring, with each ring's ends marked, and its plane.
std::vector<ClusterPoint> tag_points(const test::SyntheticTag& tag) {
  test::SyntheticScene scene;
  scene.tags.push_back(tag);
  scene.wall_x = tag.center.x() + 4;
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  std::vector<ClusterPoint> pts;
  for (int ring = 0; ring < s.rings; ++ring) {
    const size_t first = pts.size();
    for (int c = 0; c < s.columns; ++c) {
      const size_t i = s.at(0, ring, c);
      if (!s.valid(i)) continue;
      const Eigen::Vector3d p(s.x[i], s.y[i], s.z[i]);
      const Eigen::Vector3d q = tag.rotation.transpose() * (p - tag.center);
      if (std::abs(q.x()) > 1e-3 || std::abs(q.y()) > 0.61 * tag.size ||
          std::abs(q.z()) > 0.61 * tag.size)
        continue;
      ClusterPoint cp;
      cp.x = s.x[i];
      cp.y = s.y[i];
      cp.z = s.z[i];
      cp.ring = ring;
      cp.col = c;
      pts.push_back(cp);
    }
    if (pts.size() > first) pts[first].edge = pts.back().edge = true;
  }
  return pts;
}

// Largest distance from a true outer corner to the nearest found corner.
double corner_error(const TagOutline& o, const test::SyntheticTag& tag) {
  double worst = 0;
  for (double y : {-0.5, 0.5})
    for (double z : {-0.5, 0.5}) {
      const Eigen::Vector3d truth = tag.center + tag.rotation * Eigen::Vector3d(0, y, z) * tag.size;
      double best = 1e9;
      for (const auto& c : o.corners) best = std::min(best, (c - truth).norm());
      worst = std::max(worst, best);
    }
  return worst;
}

Plane plane_of(const test::SyntheticTag& tag) {
  Plane p;
  p.normal = tag.rotation.col(0);
  p.centroid = tag.center;
  return p;
}

TEST(Corners, DiamondFromFourFittedSides) {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.center = Eigen::Vector3d(7, 1, 0.2);
  tag.rotation = test::facing_sensor(tag.center, 45);
  const auto pts = tag_points(tag);
  CornerWorkspace ws;
  TagOutline o;
  const std::vector<double> sizes = {0.8, 1.2};
  ASSERT_EQ(find_corners(pts, plane_of(tag), sizes, CornerOptions{}, ws, o), Rejection::kNone);
  EXPECT_EQ(o.sides_fitted, 4);
  EXPECT_EQ(o.size_index, 1);
  EXPECT_NEAR(o.angle_deg, 45.0, 2.0);
  EXPECT_LT(corner_error(o, tag), 0.05);
  EXPECT_TRUE(o.unseen_axis.isZero());
}

TEST(Corners, SquareFromTwoSidesAndTheSize) {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.size = 0.8;
  tag.center = Eigen::Vector3d(5, -1, 0.0);
  tag.rotation = test::facing_sensor(tag.center, 0);
  const auto pts = tag_points(tag);
  CornerWorkspace ws;
  TagOutline o;
  const std::vector<double> sizes = {0.8, 1.2};
  ASSERT_EQ(find_corners(pts, plane_of(tag), sizes, CornerOptions{}, ws, o), Rejection::kNone);
  EXPECT_EQ(o.sides_fitted, 2);
  EXPECT_EQ(o.size_index, 0);
  EXPECT_NEAR(o.side_m, 0.8, 0.05);
  EXPECT_GT(std::abs(o.unseen_axis.z()), 0.99);  // top and bottom were not seen
  // Left and right sides are exact; the vertical position is known to a ring spacing.
  EXPECT_LT(corner_error(o, tag), 0.1);
}

TEST(Corners, SideLengthFarFromEverySizeIsRejected) {
  const auto& fam = tags::builtin_family("tag16h5");
  test::SyntheticTag tag;
  tag.family = &fam;
  tag.center = Eigen::Vector3d(6, 1, 0);  // clear of azimuth 0, where tag_points splits rings
  tag.rotation = test::facing_sensor(tag.center, 45);
  const auto pts = tag_points(tag);
  CornerWorkspace ws;
  TagOutline o;
  const std::vector<double> sizes = {0.5};
  EXPECT_EQ(find_corners(pts, plane_of(tag), sizes, CornerOptions{}, ws, o), Rejection::kSize);
  // Larger than a configured size by up to two board margins (0.2 m a side by default): that tag
  // on a board (the detector then requires its black square); the largest size that fits.
  for (const std::vector<double>& on_board : {std::vector<double>{0.9}, {0.5, 0.8, 0.9}}) {
    ASSERT_EQ(find_corners(pts, plane_of(tag), on_board, CornerOptions{}, ws, o), Rejection::kNone);
    EXPECT_TRUE(o.on_board);
    EXPECT_EQ(o.size_m, 0.9);
    EXPECT_NEAR(o.side_m, 1.2, 0.05);  // the board's side
  }
  // Within the size tolerance: the tag's own outline.
  ASSERT_EQ(find_corners(pts, plane_of(tag), std::vector<double>{1.1}, CornerOptions{}, ws, o),
            Rejection::kNone);
  EXPECT_FALSE(o.on_board);
  // No margin allowed: the wrong size.
  CornerOptions no_boards;
  no_boards.board_margin_m = 0.0f;
  EXPECT_EQ(find_corners(pts, plane_of(tag), std::vector<double>{0.9}, no_boards, ws, o),
            Rejection::kSize);
  const std::vector<ClusterPoint> few(pts.begin(), pts.begin() + 3);
  EXPECT_EQ(find_corners(few, plane_of(tag), sizes, CornerOptions{}, ws, o), Rejection::kCorners);
}

}  // namespace
}  // namespace lidartag::detector
