// Small geometry shared by the stages: 2-D hulls and areas (corners, pose), and the rotation
// helpers of SO(3) (the pose fit, the tracks' motion).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <vector>

namespace lidartag::detector::geometry {

// Convex hull (Andrew's monotone chain), counter-clockwise, into `hull`. `pts` is reordered, and
// points inside the hull are removed from it.
inline void convex_hull(std::vector<Eigen::Vector2d>& pts, std::vector<Eigen::Vector2d>& hull) {
  hull.clear();
  if (pts.size() < 3) {
    hull = pts;
    return;
  }
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  // Akl-Toussaint: a point strictly inside the quadrilateral of the extreme points in x and y
  // (counter-clockwise: least x, least y, most x, most y) is no vertex of the hull. Dropping
  // those before the sort leaves the hull as it was; a degenerate quadrilateral drops nothing.
  {
    std::array<Eigen::Vector2d, 4> q = {pts[0], pts[0], pts[0], pts[0]};
    for (const auto& p : pts) {
      if (p.x() < q[0].x()) q[0] = p;
      if (p.y() < q[1].y()) q[1] = p;
      if (p.x() > q[2].x()) q[2] = p;
      if (p.y() > q[3].y()) q[3] = p;
    }
    auto inside = [&](const Eigen::Vector2d& p) {
      return cross(q[0], q[1], p) > 0 && cross(q[1], q[2], p) > 0 && cross(q[2], q[3], p) > 0 &&
             cross(q[3], q[0], p) > 0;
    };
    pts.erase(std::remove_if(pts.begin(), pts.end(), inside), pts.end());
  }
  const size_t n = pts.size();
  if (n < 3) {
    hull = pts;
    return;
  }
  std::sort(pts.begin(), pts.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
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

// [w]: the cross product with w as a matrix.
inline Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

// exp([w]): the rotation by |w| about w (first order below 1e-12 rad).
inline Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double th = w.norm();
  if (th < 1e-12) return Eigen::Matrix3d::Identity() + hat(w);
  return Eigen::AngleAxisd(th, w / th).toRotationMatrix();
}

}  // namespace lidartag::detector::geometry
