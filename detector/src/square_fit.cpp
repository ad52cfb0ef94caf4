// Squares of known size in the tag's plane: the black square's outline from intensity steps, its
// fit, and a square fitted to the outline points when too few rings cross each side.
#include "lidartag/detector/square_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace lidartag::detector {

void border_crossings(std::span<const ClusterPoint> points, const RigidPose& pose,
                      const IntensityLevels& levels, bool reversed_border, double max_gap_m,
                      std::vector<BorderPoint>& out) {
  out.clear();
  if (!levels.valid || !(levels.white > levels.black)) return;
  const float mid = 0.5f * (levels.black + levels.white);
  // +1 for the outer ring's colour, -1 for the border's.
  auto side = [&](const ClusterPoint& p) {
    const bool white = p.intensity >= mid;
    return white != reversed_border ? 1 : -1;
  };
  auto crossing = [&](const ClusterPoint& a, const ClusterPoint& b) {
    const Eigen::Vector3d pa(a.x, a.y, a.z), pb(b.x, b.y, b.z);
    if ((pb - pa).norm() > max_gap_m) return;
    // Linear in intensity between the two returns: where it crosses the middle level.
    const double f = std::clamp(
        static_cast<double>(a.intensity - mid) / static_cast<double>(a.intensity - b.intensity),
        0.0, 1.0);
    const Eigen::Vector3d q = pose.apply(pa + f * (pb - pa));
    out.push_back({Eigen::Vector2d(q.y(), q.z()), a.ring});
  };
  size_t begin = 0;
  while (begin < points.size()) {
    size_t end = begin;
    while (end < points.size() && points[end].ring == points[begin].ring) ++end;
    // From the first point inward: the first step from the outer colour to the border's.
    size_t first_step = end;
    for (size_t i = begin + 1; i < end; ++i)
      if (side(points[i - 1]) > 0 && side(points[i]) < 0) {
        first_step = i;
        crossing(points[i - 1], points[i]);
        break;
      }
    // From the last point inward, not past the first step (a ring through the outer ring only).
    for (size_t i = end - 1; i > begin && i > first_step; --i)
      if (side(points[i]) > 0 && side(points[i - 1]) < 0) {
        crossing(points[i], points[i - 1]);
        break;
      }
    begin = end;
  }
}

namespace {

// A square with its angle's cosine and sine, computed once per pass over the points rather than
// once per point (they were most of the fits' cost).
struct Placed {
  explicit Placed(const Square2& sq) : s(sq), ca(std::cos(sq.angle)), sa(std::sin(sq.angle)) {}
  const Square2& s;
  double ca, sa;
};

// Signed distance of q to the boundary of the square (> 0 outside) and its gradient in (angle,
// cx, cy, half).
double square_residual(const Placed& sq, const Eigen::Vector2d& q, Eigen::Vector4d& j) {
  const Square2& s = sq.s;
  const double ca = sq.ca, sa = sq.sa;
  const Eigen::Vector2d d = q - s.center;
  // In the square's frame: its sides along the axes.
  const double u = ca * d.x() + sa * d.y(), v = -sa * d.x() + ca * d.y();
  if (std::abs(u) >= std::abs(v)) {
    const double g = u < 0 ? -1.0 : 1.0;  // d|u|/du
    // du/dangle = -sa dx + ca dy = v; du/dc = -(ca, sa)
    j = Eigen::Vector4d(g * v, -g * ca, -g * sa, -1.0);
    return std::abs(u) - s.half;
  }
  const double g = v < 0 ? -1.0 : 1.0;
  // dv/dangle = -ca dx - sa dy = -u; dv/dc = (sa, -ca)
  j = Eigen::Vector4d(-g * u, g * sa, -g * ca, -1.0);
  return std::abs(v) - s.half;
}

// Which side of `s` q lies nearest to: 0 (-u), 1 (+u), 2 (-v), 3 (+v); -1 within `corner` of a
// diagonal.
int side_of(const Placed& sq, const Eigen::Vector2d& q, double corner) {
  const double ca = sq.ca, sa = sq.sa;
  const Eigen::Vector2d d = q - sq.s.center;
  const double u = ca * d.x() + sa * d.y(), v = -sa * d.x() + ca * d.y();
  if (std::abs(std::abs(u) - std::abs(v)) < corner) return -1;
  if (std::abs(u) >= std::abs(v)) return u < 0 ? 0 : 1;
  return v < 0 ? 2 : 3;
}

}  // namespace

SquareFit fit_square(std::span<const Eigen::Vector2d> points, const Square2& start,
                     const SquareFitOptions& opt) {
  SquareFit fit;
  fit.square = start;
  // Points near the start square only; which side each lies on decides what can be placed.
  std::array<int, 4> per_side{};
  Eigen::Vector4d j;
  const Placed placed_start(start);
  for (const auto& q : points) {
    const int side = side_of(placed_start, q, opt.corner_m);
    if (side < 0 || std::abs(square_residual(placed_start, q, j)) > opt.gate_m) continue;
    ++per_side[static_cast<size_t>(side)];
    ++fit.points;
  }
  for (size_t k = 0; k < 4; ++k) fit.per_side[k] = per_side[k];
  const bool along_u = per_side[0] >= 2 || per_side[1] >= 2;
  const bool along_v = per_side[2] >= 2 || per_side[3] >= 2;
  if (fit.points < opt.min_points || !(along_u || along_v)) return fit;
  // The size needs two opposite sides or three sides.
  int sides = 0;
  for (int n : per_side) sides += n >= 1 ? 1 : 0;
  const bool size_free = opt.fit_size && (sides >= 3 || (per_side[0] >= 1 && per_side[1] >= 1) ||
                                          (per_side[2] >= 1 && per_side[3] >= 1));
  if (opt.fit_size && !size_free) return fit;

  // Gauss-Newton with Huber weights on (angle, cx, cy, half); a direction without points (the top
  // and bottom of a square mount) is held where it started.
  Square2 s = start;
  const Eigen::Vector2d eu(std::cos(start.angle), std::sin(start.angle));
  const Eigen::Vector2d ev(-eu.y(), eu.x());
  for (int it = 0; it < opt.iterations; ++it) {
    Eigen::Matrix4d jtj = Eigen::Matrix4d::Zero();
    Eigen::Vector4d jtr = Eigen::Vector4d::Zero();
    const Placed placed(s);
    for (const auto& q : points) {
      const double r = square_residual(placed, q, j);
      if (std::abs(r) > opt.gate_m || side_of(placed, q, opt.corner_m) < 0) continue;
      const double w = std::abs(r) <= opt.huber_m ? 1.0 : opt.huber_m / std::abs(r);
      jtj += w * j * j.transpose();
      jtr += w * r * j;
    }
    // Hold the unobservable: a stiff spring on the centre's component along that axis (in the
    // start square's frame) and on the size when it is known.
    Eigen::Matrix4d hold = Eigen::Matrix4d::Zero();
    const double stiff = 1e12;
    if (!along_u) hold.block<2, 2>(1, 1) += stiff * eu * eu.transpose();
    if (!along_v) hold.block<2, 2>(1, 1) += stiff * ev * ev.transpose();
    if (!size_free) hold(3, 3) += stiff;
    jtj += hold;
    jtj.diagonal().array() += 1e-9;
    const Eigen::Vector4d step = -jtj.ldlt().solve(jtr);
    if (!step.allFinite()) return fit;
    s.angle += step(0);
    s.center += step.segment<2>(1);
    s.half += step(3);
    if (!(s.half > 0.0)) return fit;
    if (step.norm() < 1e-7) break;
  }
  double sum = 0.0;
  int n = 0;
  fit.per_side = {};
  const Placed placed(s);
  for (const auto& q : points) {
    const double r = square_residual(placed, q, j);
    const int side = side_of(placed, q, opt.corner_m);
    if (std::abs(r) > opt.gate_m || side < 0) continue;
    sum += r * r;
    ++n;
    ++fit.per_side[static_cast<size_t>(side)];
  }
  if (n < opt.min_points) return fit;
  fit.points = n;
  fit.rms_m = std::sqrt(sum / n);
  fit.along_u = along_u;
  fit.along_v = along_v;
  fit.size_fitted = size_free;
  fit.square = s;
  fit.ok = true;
  return fit;
}

BorderFit refine_on_border(std::span<const BorderPoint> border, const RigidPose& pose,
                           const BorderFitOptions& opt, std::vector<Eigen::Vector2d>& buffer) {
  BorderFit out;
  out.pose = pose;
  buffer.clear();
  for (const auto& b : border) buffer.push_back(b.yz);
  Square2 start;
  start.half = opt.half_size;
  SquareFitOptions so;
  so.huber_m = opt.huber_m;
  so.gate_m = opt.gate_m;
  so.corner_m = opt.corner_m;
  so.iterations = opt.iterations;
  so.min_points = opt.min_points;
  so.fit_size = false;
  const SquareFit f = fit_square(buffer, start, so);
  out.points = f.points;
  for (int n : f.per_side) out.sides += n >= 2 ? 1 : 0;
  if (!f.ok) return out;
  // The size the crossings say, from the placed square (the size check: a configured size the
  // points contradict).
  so.fit_size = true;
  const SquareFit sized = fit_square(buffer, f.square, so);
  if (sized.ok && sized.size_fitted) out.measured_half_m = sized.square.half;
  out.rms_m = f.rms_m;
  out.along_y = f.along_u;
  out.along_z = f.along_v;
  // The square found at (c, a) in the old frame: the new frame is the old one turned by -a about
  // x and moved by -c, so that the square sits at the origin with its sides along the axes.
  const Eigen::Matrix3d rx =
      Eigen::AngleAxisd(-f.square.angle, Eigen::Vector3d::UnitX()).toRotationMatrix();
  out.pose.R = rx * pose.R;
  out.pose.p = rx * (pose.p - Eigen::Vector3d(0.0, f.square.center.x(), f.square.center.y()));
  out.ok = true;
  return out;
}

BorderFit place_on_border(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                          std::span<const RkhsDictionary> families, const IntensityLevels& levels,
                          BorderFitOptions opt, BorderWorkspace& ws) {
  BorderFit best;
  for (size_t f = 0; f < families.size(); ++f) {
    const auto& fam = families[f].family();
    bool seen = false;  // the same layout as an earlier family
    for (size_t g = 0; g < f && !seen; ++g) {
      const auto& o = families[g].family();
      seen = o.total_width == fam.total_width && o.width_at_border == fam.width_at_border &&
             o.reversed_border == fam.reversed_border;
    }
    if (seen) continue;
    const double cell = t / fam.total_width;
    border_crossings(points, pose, levels, fam.reversed_border, 2.0 * cell, ws.border);
    opt.half_size = 0.5 * cell * fam.width_at_border;
    opt.corner_m = 0.5 * cell;
    BorderFit fit = refine_on_border(ws.border, pose, opt, ws.yz);
    if (fit.measured_half_m > 0.0)
      fit.measured_size_m = fit.measured_half_m / (0.5 * fam.width_at_border) * fam.total_width;
    if (fit.ok && (!best.ok || fit.rms_m < best.rms_m)) best = fit;
  }
  return best;
}

bool fit_square_outline(std::span<const Eigen::Vector2d> edge, double min_half, double max_half,
                        const SquareFitOptions& opt, SquareFit& best) {
  best = SquareFit{};
  if (edge.size() < static_cast<size_t>(opt.min_points)) return false;
  // Starts: the points' centre, half the largest extent as the size, the angle in 15 degree steps
  // (the smallest-area rectangle of a few rings across a diamond is not the diamond).
  Eigen::Vector2d lo = edge[0], hi = edge[0];
  for (const auto& p : edge) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  for (int k = 0; k < 6; ++k) {
    Square2 start;
    start.angle = k * std::numbers::pi / 12;
    start.center = 0.5 * (lo + hi);
    // The square whose corners the points' box touches at this angle.
    const double ext = std::max(hi.x() - lo.x(), hi.y() - lo.y());
    start.half =
        std::clamp(0.5 * ext / (std::abs(std::cos(start.angle)) + std::abs(std::sin(start.angle))),
                   min_half, max_half);
    SquareFitOptions o = opt;
    o.gate_m = std::max(opt.gate_m, start.half);  // every point counts from a rough start
    SquareFit coarse = fit_square(edge, start, o);
    if (!coarse.ok) continue;
    const SquareFit f = fit_square(edge, coarse.square, opt);  // then the gate drops outliers
    if (!f.ok || f.square.half < min_half || f.square.half > max_half) continue;
    if (!best.ok || f.rms_m < best.rms_m) best = f;
  }
  return best.ok;
}

}  // namespace lidartag::detector
