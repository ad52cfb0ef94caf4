#include "lidartag/detector/corners.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <numbers>

#include "geometry.hpp"
#include "lidartag/detector/square_fit.hpp"

namespace lidartag::detector {
namespace {

struct Line2 {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d dir = Eigen::Vector2d::UnitX();  // unit
  bool ok = false;
};

uint32_t xorshift(uint32_t& s) {
  s ^= s << 13;
  s ^= s >> 17;
  s ^= s << 5;
  return s;
}

// RANSAC line, then least squares (PCA) on its inliers.
Line2 fit_line(const std::vector<Eigen::Vector2d>& pts, const CornerOptions& opt, uint32_t seed) {
  Line2 best;
  const size_t n = pts.size();
  if (static_cast<int>(n) < opt.min_line_points || n < 2) return best;
  uint32_t s = seed;
  int best_count = -1;
  for (int it = 0; it < opt.line_iterations; ++it) {
    const auto& a = pts[xorshift(s) % n];
    const auto& b = pts[xorshift(s) % n];
    Eigen::Vector2d d = b - a;
    if (d.norm() < 1e-6) continue;
    d.normalize();
    const Eigen::Vector2d nrm(-d.y(), d.x());
    int count = 0;
    for (const auto& p : pts) count += std::abs(nrm.dot(p - a)) <= opt.line_inlier_m ? 1 : 0;
    if (count > best_count) {
      best_count = count;
      best.point = a;
      best.dir = d;
    }
  }
  if (best_count < opt.min_line_points) return best;
  const Eigen::Vector2d nrm(-best.dir.y(), best.dir.x());
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int m = 0;
  for (const auto& p : pts)
    if (std::abs(nrm.dot(p - best.point)) <= opt.line_inlier_m) {
      mean += p;
      ++m;
    }
  mean /= m;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : pts)
    if (std::abs(nrm.dot(p - best.point)) <= opt.line_inlier_m)
      cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
  best.point = mean;
  best.dir = es.eigenvectors().col(1);
  best.ok = true;
  return best;
}

Eigen::Vector2d intersect(const Line2& a, const Line2& b) {
  // a.point + s a.dir = b.point + r b.dir
  Eigen::Matrix2d m;
  m << a.dir, -b.dir;
  const Eigen::Vector2d sr = m.colPivHouseholderQr().solve(b.point - a.point);
  return a.point + sr(0) * a.dir;
}

// The configured size an outline of side `side` shows: the nearest within size_tolerance (the
// tag's own outline), else the largest smaller one whose board margin, up to board_margin_m a
// side, makes up the rest (a tag on a board). -1 for none.
int match_size(std::span<const double> sizes, double side, const CornerOptions& opt,
               bool& on_board) {
  on_board = false;
  size_t best = 0;
  for (size_t i = 1; i < sizes.size(); ++i)
    if (std::abs(sizes[i] - side) < std::abs(sizes[best] - side)) best = i;
  if (std::abs(sizes[best] - side) <= opt.size_tolerance * sizes[best])
    return static_cast<int>(best);
  int board = -1;
  for (size_t i = 0; i < sizes.size(); ++i) {
    const double t = sizes[i];
    if (side > t && side <= t * (1.0 + opt.size_tolerance) + 2.0 * opt.board_margin_m &&
        (board < 0 || t > sizes[static_cast<size_t>(board)]))
      board = static_cast<int>(i);
  }
  on_board = board >= 0;
  return board;
}

// The outline from a square fitted to the edge points (in the plane basis u, v around c) when no
// pair of opposite sides has a line.
Rejection square_outline(std::span<const Eigen::Vector2d> edge, const Eigen::Vector3d& c,
                         const Eigen::Vector3d& u, const Eigen::Vector3d& v,
                         std::span<const double> sizes, const CornerOptions& opt, TagOutline& out) {
  const auto [lo, hi] = std::minmax_element(sizes.begin(), sizes.end());
  SquareFitOptions so;
  so.fit_size = true;
  so.gate_m = 0.05 * *hi;
  so.huber_m = 0.01 * *hi;
  so.min_points = 6;
  SquareFit fit;
  if (!fit_square_outline(edge, 0.5 * *lo * (1.0 - opt.size_tolerance),
                          0.5 * (*hi * (1.0 + opt.size_tolerance) + 2.0 * opt.board_margin_m), so,
                          fit))
    return Rejection::kCorners;
  const double side = 2.0 * fit.square.half;
  if (fit.rms_m > opt.square_fit_max_rms * side) return Rejection::kCorners;
  out.side_m = side;
  const int best = match_size(sizes, side, opt, out.on_board);
  if (best < 0) return Rejection::kSize;
  out.size_index = best;
  out.size_m = sizes[static_cast<size_t>(best)];
  out.square_fit = true;
  for (int n : fit.per_side) out.sides_fitted += n > 0 ? 1 : 0;
  const Eigen::Vector2d eu(std::cos(fit.square.angle), std::sin(fit.square.angle));
  const Eigen::Vector2d ev(-eu.y(), eu.x());
  const auto to3 = [&](const Eigen::Vector2d& p) { return c + p.x() * u + p.y() * v; };
  const double h = fit.square.half;
  const Eigen::Vector2d m = fit.square.center;
  out.corners = {to3(m - h * eu - h * ev), to3(m + h * eu - h * ev), to3(m + h * eu + h * ev),
                 to3(m - h * eu + h * ev)};
  out.center = to3(m);
  // The direction the points could not place (a square mount): decoding searches it.
  if (!fit.along_u) out.unseen_axis = eu.x() * u + eu.y() * v;
  if (!fit.along_v) out.unseen_axis = ev.x() * u + ev.y() * v;
  const double quarter = std::numbers::pi / 2;
  out.angle_deg =
      std::fmod(std::fmod(fit.square.angle, quarter) + quarter, quarter) * 180.0 / std::numbers::pi;
  return Rejection::kNone;
}

}  // namespace

void plane_basis(const Eigen::Vector3d& normal, Eigen::Vector3d& u, Eigen::Vector3d& v) {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ() - normal.z() * normal;
  if (up.norm() < 0.2) up = Eigen::Vector3d::UnitX() - normal.x() * normal;  // a level plane
  v = up.normalized();
  u = v.cross(normal);  // tag frame: y = z cross x
}

Rejection find_corners(std::span<const ClusterPoint> points, const Plane& plane,
                       std::span<const double> sizes, const CornerOptions& opt, CornerWorkspace& ws,
                       TagOutline& out) {
  out = TagOutline{};
  if (sizes.empty()) return Rejection::kSize;
  Eigen::Vector3d u, v;
  plane_basis(plane.normal, u, v);
  const Eigen::Vector3d c = plane.centroid;
  ws.edge.clear();
  for (const auto& p : points)
    if (p.edge) {
      const Eigen::Vector3d q = Eigen::Vector3d(p.x, p.y, p.z) - c;
      ws.edge.emplace_back(q.dot(u), q.dot(v));
    }
  if (ws.edge.size() < 6) return Rejection::kCorners;
  ws.scratch = ws.edge;
  geometry::convex_hull(ws.scratch, ws.hull);
  if (ws.hull.size() < 3) return Rejection::kCorners;

  // Smallest-area enclosing rectangle: one side lies along a hull edge.
  double best_area = std::numeric_limits<double>::infinity(), phi = 0.0;
  for (size_t i = 0; i < ws.hull.size(); ++i) {
    const Eigen::Vector2d e = ws.hull[(i + 1) % ws.hull.size()] - ws.hull[i];
    if (e.norm() < 1e-9) continue;
    const double a = std::atan2(e.y(), e.x());
    const Eigen::Vector2d d1(std::cos(a), std::sin(a)), d2(-std::sin(a), std::cos(a));
    double lo1 = 1e9, hi1 = -1e9, lo2 = 1e9, hi2 = -1e9;
    for (const auto& p : ws.hull) {
      lo1 = std::min(lo1, p.dot(d1));
      hi1 = std::max(hi1, p.dot(d1));
      lo2 = std::min(lo2, p.dot(d2));
      hi2 = std::max(hi2, p.dot(d2));
    }
    const double area = (hi1 - lo1) * (hi2 - lo2);
    if (area < best_area) {
      best_area = area;
      phi = a;
    }
  }
  const double quarter = std::numbers::pi / 2;
  phi = std::fmod(std::fmod(phi, quarter) + quarter, quarter);  // [0, 90 deg)
  const Eigen::Vector2d d1(std::cos(phi), std::sin(phi)), d2(-std::sin(phi), std::cos(phi));
  double lo1 = 1e9, hi1 = -1e9, lo2 = 1e9, hi2 = -1e9;
  for (const auto& p : ws.edge) {
    lo1 = std::min(lo1, p.dot(d1));
    hi1 = std::max(hi1, p.dot(d1));
    lo2 = std::min(lo2, p.dot(d2));
    hi2 = std::max(hi2, p.dot(d2));
  }
  // Sides: 0 at lo1, 1 at hi1 (along d2); 2 at lo2, 3 at hi2 (along d1).
  for (auto& s : ws.side) s.clear();
  const double excl = opt.corner_exclusion * std::max(hi1 - lo1, hi2 - lo2);
  for (const auto& p : ws.edge) {
    const double a = p.dot(d1), b = p.dot(d2);
    const std::array<double, 4> dist = {a - lo1, hi1 - a, b - lo2, hi2 - b};
    int k = 0;
    for (int j = 1; j < 4; ++j)
      if (dist[static_cast<size_t>(j)] < dist[static_cast<size_t>(k)]) k = j;
    bool ambiguous = false;
    for (int j = 0; j < 4; ++j)
      if (j != k && dist[static_cast<size_t>(j)] < excl) ambiguous = true;
    if (!ambiguous) ws.side[static_cast<size_t>(k)].push_back(p);
  }
  std::array<Line2, 4> line;
  const double max_angle = opt.max_side_angle_deg * std::numbers::pi / 180.0;
  for (size_t k = 0; k < 4; ++k) {
    line[k] = fit_line(ws.side[k], opt, 0x2545f491u + static_cast<uint32_t>(k));
    const Eigen::Vector2d& expect = k < 2 ? d2 : d1;
    if (line[k].ok && std::abs(line[k].dir.dot(expect)) < std::cos(max_angle)) line[k].ok = false;
    if (line[k].ok) {
      if (line[k].dir.dot(expect) < 0) line[k].dir = -line[k].dir;
      ++out.sides_fitted;
    }
  }
  // Side length from each pair of opposite sides that both have a line.
  auto spacing = [](const Line2& a, const Line2& b) {
    const Eigen::Vector2d na(-a.dir.y(), a.dir.x()), nb(-b.dir.y(), b.dir.x());
    return 0.5 * (std::abs(na.dot(b.point - a.point)) + std::abs(nb.dot(a.point - b.point)));
  };
  double sum = 0.0;
  int pairs = 0;
  if (line[0].ok && line[1].ok) {
    sum += spacing(line[0], line[1]);
    ++pairs;
  }
  if (line[2].ok && line[3].ok) {
    sum += spacing(line[2], line[3]);
    ++pairs;
  }
  if (pairs == 0)
    return opt.square_fit ? square_outline(ws.edge, c, u, v, sizes, opt, out) : Rejection::kCorners;
  out.side_m = sum / pairs;
  const int best = match_size(sizes, out.side_m, opt, out.on_board);
  if (best < 0) return Rejection::kSize;
  // Missing sides are completed with the outline's size: the board's, for a tag on a board.
  const double t = out.on_board ? out.side_m : sizes[static_cast<size_t>(best)];
  out.size_index = best;
  out.size_m = sizes[static_cast<size_t>(best)];
  // Complete the missing sides from the tag size: one side of a pair from the other, both sides
  // of an unseen pair centred on the points' extent.
  auto complete = [&](Line2& lo, Line2& hi, const Eigen::Vector2d& across, double lo_ext,
                      double hi_ext, const Eigen::Vector2d& along) {
    if (lo.ok && hi.ok) return;
    if (lo.ok) {
      hi = lo;
      hi.point = lo.point + t * across;
    } else if (hi.ok) {
      lo = hi;
      lo.point = hi.point - t * across;
    } else {
      const double mid = 0.5 * (lo_ext + hi_ext);
      lo.point = (mid - t / 2) * across;
      hi.point = (mid + t / 2) * across;
      lo.dir = hi.dir = along;
    }
    lo.ok = hi.ok = true;
  };
  const Eigen::Vector3d d1s = d1.x() * u + d1.y() * v, d2s = d2.x() * u + d2.y() * v;
  if (!line[0].ok && !line[1].ok) out.unseen_axis = d1s;
  if (!line[2].ok && !line[3].ok) out.unseen_axis = d2s;
  complete(line[0], line[1], d1, lo1, hi1, d2);
  complete(line[2], line[3], d2, lo2, hi2, d1);
  const std::array<Eigen::Vector2d, 4> c2 = {
      intersect(line[0], line[2]), intersect(line[1], line[2]), intersect(line[1], line[3]),
      intersect(line[0], line[3])};
  Eigen::Vector2d mid = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < 4; ++k) {
    out.corners[k] = c + c2[k].x() * u + c2[k].y() * v;
    mid += c2[k];
  }
  mid /= 4.0;
  out.center = c + mid.x() * u + mid.y() * v;
  out.angle_deg = phi * 180.0 / std::numbers::pi;
  return Rejection::kNone;
}

}  // namespace lidartag::detector
