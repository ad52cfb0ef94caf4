#include "lidartag/detector/pose_fit.hpp"

#include <nlopt.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "geometry.hpp"
#include "lidartag/detector/cluster_validation.hpp"

namespace lidartag::detector {
namespace {

constexpr std::array<std::pair<PoseAlgorithm, std::string_view>, 5> kNames = {{
    {PoseAlgorithm::kMMA, "mma"},
    {PoseAlgorithm::kCCSAQ, "ccsaq"},
    {PoseAlgorithm::kSLSQP, "slsqp"},
    {PoseAlgorithm::kSBPLX, "sbplx"},
    {PoseAlgorithm::kBOBYQA, "bobyqa"},
}};

nlopt_algorithm to_nlopt(PoseAlgorithm a) {
  switch (a) {
    case PoseAlgorithm::kMMA:
      return NLOPT_LD_MMA;
    case PoseAlgorithm::kCCSAQ:
      return NLOPT_LD_CCSAQ;
    case PoseAlgorithm::kSLSQP:
      return NLOPT_LD_SLSQP;
    case PoseAlgorithm::kSBPLX:
      return NLOPT_LN_SBPLX;
    case PoseAlgorithm::kBOBYQA:
      return NLOPT_LN_BOBYQA;
  }
  return NLOPT_LD_MMA;
}

using geometry::exp_so3;
using geometry::hat;

// Right Jacobian of SO(3): Exp(w + dw) ~ Exp(w) Exp(J_r(w) dw).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& w) {
  const double th = w.norm();
  const Eigen::Matrix3d W = hat(w);
  if (th < 1e-6) return Eigen::Matrix3d::Identity() - 0.5 * W;
  const double th2 = th * th;
  return Eigen::Matrix3d::Identity() - (1 - std::cos(th)) / th2 * W +
         (th - std::sin(th)) / (th2 * th) * W * W;
}

}  // namespace

std::string_view pose_algorithm_name(PoseAlgorithm a) {
  for (const auto& [k, n] : kNames)
    if (k == a) return n;
  return "?";
}

std::optional<PoseAlgorithm> pose_algorithm_from_name(std::string_view name) {
  for (const auto& [k, n] : kNames)
    if (n == name) return k;
  return std::nullopt;
}

std::array<Eigen::Vector3d, 4> template_corners(double t) {
  const double h = t / 2;
  return {Eigen::Vector3d(0, -h, -h), Eigen::Vector3d(0, h, -h), Eigen::Vector3d(0, h, h),
          Eigen::Vector3d(0, -h, h)};
}

RigidPose procrustes_initial_guess(const std::array<Eigen::Vector3d, 4>& corners, double t) {
  const auto tmpl = template_corners(t);
  Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
  for (const auto& c : corners) x0 += c;
  x0 /= 4.0;
  // M = Xbar X^T = U S V^T, R = U V^T (with the sign fix that keeps det R = +1).
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < 4; ++i) m += tmpl[i] * (corners[i] - x0).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  RigidPose pose;
  pose.R = svd.matrixU() * d * svd.matrixV().transpose();
  pose.p = -pose.R * x0;  // p = -R X_0
  return pose;
}

double fitting_cost(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                    double epsilon) {
  // eq. (7) per coordinate, without branches, into four partial sums (one long chain of
  // dependent additions would bound the loop by their latency).
  const double half = t / 2;
  std::array<double, 4> c{};
  for (size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const Eigen::Vector3d q = pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    c[i % 4] += std::max(std::abs(q.x()) - epsilon, 0.0) + std::max(std::abs(q.y()) - half, 0.0) +
                std::max(std::abs(q.z()) - half, 0.0);
  }
  return (c[0] + c[1]) + (c[2] + c[3]);
}

// Points per block of the cost loop: a fixed trip count that the compiler vectorises.
constexpr size_t kLanes = 4;
constexpr size_t kChunk = 16 * kLanes;

struct PoseSolver::Impl {
  nlopt_opt opt = nullptr;
  bool gradient_based = true;
  // R0 (X_i - c): the points, centred and pre-rotated, as float arrays padded with zero-weight
  // points to a multiple of kLanes; w their weights.
  std::vector<float> yx, yy, yz, w;
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Vector3d q0 = Eigen::Vector3d::Zero();
  double half = 0.5, eps = 0.01;
  int evaluations = 0;
};

PoseSolver::PoseSolver(PoseAlgorithm algorithm) : impl_(new Impl) {
  impl_->opt = nlopt_create(to_nlopt(algorithm), 6);
  if (impl_->opt == nullptr) {
    delete impl_;
    throw std::runtime_error("NLopt: cannot create the pose solver");
  }
  impl_->gradient_based = algorithm == PoseAlgorithm::kMMA || algorithm == PoseAlgorithm::kCCSAQ ||
                          algorithm == PoseAlgorithm::kSLSQP;
}

PoseSolver::~PoseSolver() {
  nlopt_destroy(impl_->opt);
  delete impl_;
}

// theta = (w, dq): x_bar_i = Exp(w) y_i + q0 + dq. Cost eq. (8); closed-form gradient:
// dC/ddq = sum r_i, dC/dw = J_r(w)^T sum y_i x (Exp(w)^T r_i), r_i the per-axis L1 slopes. With
// y_i = Exp(w)^T (x_bar_i - q): sum y_i x (Exp(w)^T r_i) = Exp(w)^T (sum x_bar_i x r_i - q x sum
// r_i), which the loop accumulates without rotating anything back.
double PoseSolver::objective(const double* theta, double* grad) const {
  Impl& s = *impl_;
  ++s.evaluations;
  const Eigen::Vector3d w(theta[0], theta[1], theta[2]);
  const Eigen::Vector3d q = s.q0 + Eigen::Vector3d(theta[3], theta[4], theta[5]);
  const Eigen::Matrix3d R = exp_so3(w);
  // This loop is the pose stage's cost (points x evaluations): float, without branches, in blocks
  // of kLanes points with one partial sum per lane, so that it is vectorised. The points are
  // centred on their mean (within a tag's half diagonal): float keeps them to a micrometre.
  const auto r00 = static_cast<float>(R(0, 0)), r01 = static_cast<float>(R(0, 1)),
             r02 = static_cast<float>(R(0, 2)), r10 = static_cast<float>(R(1, 0)),
             r11 = static_cast<float>(R(1, 1)), r12 = static_cast<float>(R(1, 2)),
             r20 = static_cast<float>(R(2, 0)), r21 = static_cast<float>(R(2, 1)),
             r22 = static_cast<float>(R(2, 2));
  const auto q0 = static_cast<float>(q.x()), q1 = static_cast<float>(q.y()),
             q2 = static_cast<float>(q.z()), eps = static_cast<float>(s.eps),
             half = static_cast<float>(s.half);
  // Float partial sums over chunks of kChunk points, added up in double: the rounding does not
  // grow with the number of points.
  double total = 0.0;
  Eigen::Vector3d gq = Eigen::Vector3d::Zero(), h = Eigen::Vector3d::Zero();
  const size_t n = s.w.size();
  for (size_t c0 = 0; c0 < n; c0 += kChunk) {
    std::array<float, kLanes> cost{}, g0{}, g1{}, g2{}, h0{}, h1{}, h2{};
    const size_t c1 = std::min(n, c0 + kChunk);
    for (size_t b = c0; b < c1; b += kLanes) {
      const float *px = s.yx.data() + b, *py = s.yy.data() + b, *pz = s.yz.data() + b,
                  *pw = s.w.data() + b;
      for (size_t l = 0; l < kLanes; ++l) {
        const float y0 = px[l], y1 = py[l], y2 = pz[l], wi = pw[l];
        const float x0 = r00 * y0 + r01 * y1 + r02 * y2 + q0;
        const float x1 = r10 * y0 + r11 * y1 + r12 * y2 + q1;
        const float x2 = r20 * y0 + r21 * y1 + r22 * y2 + q2;
        // eq. (7) per coordinate and its slope r (0 inside the template, +-w outside).
        const float a0 = std::fabs(x0) - eps, a1 = std::fabs(x1) - half, a2 = std::fabs(x2) - half;
        cost[l] += wi * (std::max(a0, 0.0f) + std::max(a1, 0.0f) + std::max(a2, 0.0f));
        const float e0 = a0 > 0.0f ? std::copysign(wi, x0) : 0.0f;
        const float e1 = a1 > 0.0f ? std::copysign(wi, x1) : 0.0f;
        const float e2 = a2 > 0.0f ? std::copysign(wi, x2) : 0.0f;
        g0[l] += e0;
        g1[l] += e1;
        g2[l] += e2;
        h0[l] += x1 * e2 - x2 * e1;  // x_bar x r
        h1[l] += x2 * e0 - x0 * e2;
        h2[l] += x0 * e1 - x1 * e0;
      }
    }
    for (size_t l = 0; l < kLanes; ++l) {
      total += cost[l];
      gq += Eigen::Vector3d(g0[l], g1[l], g2[l]);
      h += Eigen::Vector3d(h0[l], h1[l], h2[l]);
    }
  }
  if (grad != nullptr) {
    const Eigen::Vector3d gw = right_jacobian(w).transpose() * (R.transpose() * (h - q.cross(gq)));
    for (int k = 0; k < 3; ++k) {
      grad[k] = gw(k);
      grad[k + 3] = gq(k);
    }
  }
  return total;
}

PoseFitResult PoseSolver::fit(std::span<const ClusterPoint> points, double t, double epsilon,
                              const RigidPose& initial, const PoseOptions& opt,
                              std::span<const float> weights) {
  Impl& s = *impl_;
  PoseFitResult res;
  res.pose = initial;
  s.c.setZero();
  for (const auto& p : points) s.c += Eigen::Vector3d(p.x, p.y, p.z);
  if (!points.empty()) s.c /= static_cast<double>(points.size());
  s.R0 = initial.R;
  s.q0 = initial.R * s.c + initial.p;
  const size_t padded = (points.size() + kLanes - 1) / kLanes * kLanes;
  s.yx.assign(padded, 0.0f);
  s.yy.assign(padded, 0.0f);
  s.yz.assign(padded, 0.0f);
  s.w.assign(padded, 0.0f);
  const bool weighted = weights.size() == points.size();
  for (size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const Eigen::Vector3f y = (s.R0 * (Eigen::Vector3d(p.x, p.y, p.z) - s.c)).cast<float>();
    s.yx[i] = y.x();
    s.yy[i] = y.y();
    s.yz[i] = y.z();
    s.w[i] = weighted ? weights[i] : 1.0f;
  }
  s.half = t / 2;
  s.eps = epsilon;
  s.evaluations = 0;
  std::array<double, 6> x{}, lb{}, ub{};
  for (size_t k = 0; k < 3; ++k) {
    lb[k] = -opt.rotation_bound_rad;
    ub[k] = opt.rotation_bound_rad;
    lb[k + 3] = -opt.translation_bound_m;
    ub[k + 3] = opt.translation_bound_m;
  }
  res.initial_cost = objective(x.data(), nullptr);
  nlopt_set_lower_bounds(s.opt, lb.data());
  nlopt_set_upper_bounds(s.opt, ub.data());
  nlopt_set_xtol_rel(s.opt, opt.xtol_rel);
  nlopt_set_xtol_abs1(s.opt, opt.xtol_abs);
  nlopt_set_maxeval(s.opt, opt.max_evaluations);
  if (!s.gradient_based) {
    const std::array<double, 6> step = {0.02, 0.02, 0.02, 0.02, 0.02, 0.02};
    nlopt_set_initial_step(s.opt, step.data());
  }
  nlopt_set_min_objective(
      s.opt,
      [](unsigned, const double* th, double* g, void* self) {
        return static_cast<const PoseSolver*>(self)->objective(th, g);
      },
      this);
  double f = res.initial_cost;
  const nlopt_result rc = nlopt_optimize(s.opt, x.data(), &f);
  res.solver_ok = rc > 0;
  res.evaluations = s.evaluations;
  if (rc < 0 || !std::isfinite(f) || f > res.initial_cost) {
    x.fill(0.0);
    f = res.initial_cost;
  }
  const Eigen::Matrix3d R = exp_so3(Eigen::Vector3d(x[0], x[1], x[2])) * s.R0;
  const Eigen::Vector3d q = s.q0 + Eigen::Vector3d(x[3], x[4], x[5]);
  res.pose.R = R;
  res.pose.p = q - R * s.c;  // x_bar = R (X - c) + q
  res.cost = f;
  return res;
}

void select_pose_points(std::span<const ClusterPoint> points, int max_points,
                        std::vector<ClusterPoint>& subset, std::vector<float>& weights) {
  subset.clear();
  weights.clear();
  size_t edges = 0;
  for (const auto& p : points) edges += p.edge ? 1 : 0;
  const size_t cap = static_cast<size_t>(std::max(max_points, 8));
  const size_t interior = points.size() - edges;
  const size_t keep = cap > edges ? cap - edges : 0;
  const size_t stride = keep > 0 ? std::max<size_t>(1, (interior + keep - 1) / keep) : 0;
  size_t n_interior = 0;
  for (const auto& p : points) {
    if (p.edge || (stride > 0 && n_interior++ % stride == 0)) {
      subset.push_back(p);
      weights.push_back(p.edge ? 1.0f : 0.0f);
    }
  }
  const size_t kept = subset.size() - edges;
  const float interior_weight =
      kept > 0 ? static_cast<float>(interior) / static_cast<float>(kept) : 0.0f;
  for (size_t i = 0; i < subset.size(); ++i)
    if (!subset[i].edge) weights[i] = interior_weight;
}

namespace {

// The polish: opt.polish_evaluations evaluations within 2 cm and 0.02 rad of its start.
PoseOptions polish_options(const PoseOptions& opt) {
  PoseOptions polish = opt;
  polish.max_evaluations = opt.polish_evaluations;
  polish.translation_bound_m = 0.02;
  polish.rotation_bound_rad = 0.02;
  return polish;
}

}  // namespace

PoseFitResult fit_tag_pose(PoseSolver& solver, std::span<const ClusterPoint> points,
                           const RigidPose& initial, double t_fit, double epsilon,
                           const PoseOptions& opt, TagPoseWorkspace& ws) {
  select_pose_points(points, opt.max_points, ws.subset, ws.weights);
  const bool subsampled = ws.subset.size() < points.size();
  const bool polished = subsampled && opt.polish_evaluations > 0;
  const bool now = polished && (opt.polish_max_points == 0 ||
                                points.size() <= static_cast<size_t>(opt.polish_max_points));
  // A subsample's own cost at its optimum is biased low: the retry decides on every point's.
  auto fit_from = [&](const RigidPose& start) {
    PoseFitResult fit = solver.fit(ws.subset, t_fit, epsilon, start, opt, ws.weights);
    if (subsampled && (opt.retry_mean_cost_m > 0.0 || !now))
      fit.cost = fitting_cost(points, fit.pose, t_fit, epsilon);
    return fit;
  };
  PoseFitResult fit = fit_from(initial);
  // The square's other guess: turned 45 degrees in its plane (the tag frame's x is the normal;
  // +45 and -45 give the same square).
  if (opt.retry_mean_cost_m > 0.0 &&
      fit.cost > opt.retry_mean_cost_m * static_cast<double>(points.size())) {
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(std::numbers::pi / 4.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
    const PoseFitResult other = fit_from({turn * initial.R, turn * initial.p});
    if (other.cost < fit.cost) fit = other;
  }
  // Only the better guess is polished (the subsample's depth term is noisier), and a cluster of
  // more than polish_max_points only when the caller asks for it (polish_tag_pose).
  if (now) return polish_tag_pose(solver, points, fit.pose, t_fit, epsilon, opt);
  fit.polish_pending = polished;
  return fit;
}

PoseFitResult polish_tag_pose(PoseSolver& solver, std::span<const ClusterPoint> points,
                              const RigidPose& start, double t_fit, double epsilon,
                              const PoseOptions& opt) {
  return solver.fit(points, t_fit, epsilon, start, polish_options(opt));
}

double coverage_ratio(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                      std::vector<Eigen::Vector2d>& buffer, std::vector<Eigen::Vector2d>& hull) {
  buffer.clear();
  for (const auto& p : points) {
    const Eigen::Vector3d q = pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    buffer.emplace_back(q.y(), q.z());
  }
  geometry::convex_hull(buffer, hull);
  if (hull.size() < 3) return 0.0;
  return geometry::polygon_area(hull) / (t * t);
}

namespace {

// The median of the first components of buffer[from, end) (reordered); 0 when empty.
double median_x(std::vector<Eigen::Vector2d>& buffer, size_t from) {
  if (buffer.size() <= from) return 0.0;
  const auto begin = buffer.begin() + static_cast<std::ptrdiff_t>(from);
  const auto mid = begin + static_cast<std::ptrdiff_t>((buffer.size() - from) / 2);
  std::nth_element(
      begin, mid, buffer.end(),
      [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x(); });
  return mid->x();
}

}  // namespace

double sampled_coverage(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                        std::vector<Eigen::Vector2d>& buffer, std::vector<Eigen::Vector2d>& hull) {
  // The points in the tag's y-z plane, pulled back once (`hull` is their scratch until the end).
  std::vector<Eigen::Vector2d>& yz = hull;
  yz.clear();
  for (const auto& p : points) {
    const Eigen::Vector3d q = pose.apply(Eigen::Vector3d(p.x, p.y, p.z));
    yz.emplace_back(q.y(), q.z());
  }
  // Each ring's run of points [i, run_end(i)); the rings' direction from the longest one.
  const auto run_end = [&](size_t i) {
    size_t j = i + 1;
    while (j < points.size() && points[j].ring == points[i].ring) ++j;
    return j;
  };
  Eigen::Vector2d dir = Eigen::Vector2d::Zero();
  double longest = 0.0;
  for (size_t i = 0, j = 0; i < points.size(); i = j) {
    j = run_end(i);
    const Eigen::Vector2d d = yz[j - 1] - yz[i];
    if (d.norm() > longest) {
      longest = d.norm();
      dir = d / longest;
    }
  }
  if (!(longest > 0.0)) return 1.0;
  const Eigen::Vector2d across(-dir.y(), dir.x());
  // The column step: the median gap between neighbouring points of a ring, along the rings.
  buffer.clear();
  for (size_t i = 1; i < points.size(); ++i)
    if (points[i].ring == points[i - 1].ring)
      buffer.emplace_back(std::abs((yz[i] - yz[i - 1]).dot(dir)), 0.0);
  const double step = median_x(buffer, 0);
  // The ring spacing: the median gap between neighbouring rings' mean offsets across them.
  buffer.clear();
  for (size_t i = 0, j = 0; i < points.size(); i = j) {
    j = run_end(i);
    double sum = 0.0;
    for (size_t k = i; k < j; ++k) sum += yz[k].dot(across);
    buffer.emplace_back(sum / static_cast<double>(j - i), 0.0);
  }
  std::sort(buffer.begin(), buffer.end(),
            [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x(); });
  const size_t rings = buffer.size();
  for (size_t k = 1; k < rings; ++k) buffer.emplace_back(buffer[k].x() - buffer[k - 1].x(), 0.0);
  const double spacing = median_x(buffer, rings);
  const double h = t / 2.0;
  const double reach = h * (std::abs(across.x()) + std::abs(across.y()));
  // No sampling to speak of, or rings too close to be a LiDAR's (duplicates): nothing lost.
  if (rings < 2 || !(step > 0.0) || !(spacing > 0.0) || 2.0 * reach / spacing > 4096.0) return 1.0;
  // The square [-t/2, t/2]^2 sampled on that grid: each line's first and last point.
  buffer.clear();
  for (double o = -reach + spacing / 2.0; o <= reach; o += spacing) {
    double a0 = -std::numeric_limits<double>::infinity(), a1 = -a0;
    for (int c = 0; c < 2; ++c) {
      const double base = o * across[c];
      if (std::abs(dir[c]) < 1e-12) {
        if (std::abs(base) > h) a0 = a1 + 1.0;  // the line misses the square
        continue;
      }
      const double lo = (-h - base) / dir[c], hi = (h - base) / dir[c];
      a0 = std::max(a0, std::min(lo, hi));
      a1 = std::min(a1, std::max(lo, hi));
    }
    const double first = a0 + step / 2.0;
    if (!(first <= a1)) continue;
    const double last = first + std::floor((a1 - first) / step) * step;
    buffer.push_back(o * across + first * dir);
    buffer.push_back(o * across + last * dir);
  }
  geometry::convex_hull(buffer, hull);
  if (hull.size() < 3) return 1.0;
  return std::min(1.0, geometry::polygon_area(hull) / (t * t));
}

double coverage_bound(const std::vector<Eigen::Vector2d>& plane_hull, double t) {
  if (plane_hull.size() < 3) return 0.0;
  return geometry::polygon_area(plane_hull) / (t * t) / kCoverageBoundSlack;
}

double track_coverage_share(std::span<const ClusterPoint> points, const RigidPose& pose, double t,
                            std::vector<Eigen::Vector2d>& buffer,
                            std::vector<Eigen::Vector2d>& hull) {
  const double rings = rings_in(points);
  return sampled_coverage(points, pose, t, buffer, hull) * rings / (rings + 1.0);
}

}  // namespace lidartag::detector
