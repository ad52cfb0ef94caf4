// Small 2-D geometry shared by the corner and pose stages.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <vector>

namespace lidartag::detector::geometry {

// Convex hull (Andrew's monotone chain), counter-clockwise, into `hull`. `pts` is reordered.
inline void convex_hull(std::vector<Eigen::Vector2d>& pts, std::vector<Eigen::Vector2d>& hull) {
  hull.clear();
  const size_t n = pts.size();
  if (n < 3) {
    hull = pts;
    return;
  }
  std::sort(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  hull.resize(2 * n);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (size_t i = n - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i - 1]) <= 0) --k;
    hull[k++] = pts[i - 1];
  }
  hull.resize(k - 1);
}

// Surveyor's (shoelace) formula for a simple polygon.
inline double polygon_area(const std::vector<Eigen::Vector2d>& poly) {
  double a = 0.0;
  for (size_t i = 0, n = poly.size(); i < n; ++i) {
    const auto& p = poly[i];
    const auto& q = poly[(i + 1) % n];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * std::abs(a);
}

}  // namespace lidartag::detector::geometry
