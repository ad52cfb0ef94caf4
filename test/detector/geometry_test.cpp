// The 2-D geometry the corner and pose stages share (detector/src/geometry.hpp).
#include "geometry.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace lidartag::detector::geometry {
namespace {

// Andrew's monotone chain on every point: what convex_hull must return with its interior points
// dropped before the sort.
std::vector<Eigen::Vector2d> plain_hull(std::vector<Eigen::Vector2d> pts) {
  if (pts.size() < 3) return pts;
  std::sort(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2d> h(2 * pts.size());
  size_t k = 0;
  for (const auto& p : pts) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p) <= 0) --k;
    h[k++] = p;
  }
  for (size_t i = pts.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], pts[i - 1]) <= 0) --k;
    h[k++] = pts[i - 1];
  }
  h.resize(k - 1);
  return h;
}

TEST(Geometry, ConvexHullIsThatOfEveryPoint) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::vector<Eigen::Vector2d>> sets;
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<Eigen::Vector2d> pts;
    const int n = 1 + static_cast<int>(rng() % 400);
    const int kind = trial % 5;
    for (int i = 0; i < n; ++i) {
      const double a = u(rng), b = u(rng);
      if (kind == 0) pts.emplace_back(a, b);          // a filled square
      if (kind == 1) pts.emplace_back(a + b, a - b);  // a diamond (a tag turned 45 degrees)
      if (kind == 2) {                                // on a circle: every point on the hull
        const double t = std::numbers::pi * a;
        pts.emplace_back(std::cos(t), std::sin(t));
      }
      if (kind == 3) pts.emplace_back(std::round(4 * a), std::round(4 * b));  // a grid, repeats
      if (kind == 4) pts.emplace_back(a, 2 * a + 1);                          // collinear
    }
    sets.push_back(pts);
  }
  std::vector<Eigen::Vector2d> hull;
  for (size_t s = 0; s < sets.size(); ++s) {
    const std::vector<Eigen::Vector2d> want = plain_hull(sets[s]);
    auto pts = sets[s];
    convex_hull(pts, hull);
    ASSERT_EQ(hull.size(), want.size()) << "set " << s;
    for (size_t i = 0; i < hull.size(); ++i) EXPECT_EQ(hull[i], want[i]) << "set " << s;
    EXPECT_EQ(polygon_area(hull), polygon_area(want)) << "set " << s;
  }
}

}  // namespace
}  // namespace lidartag::detector::geometry
