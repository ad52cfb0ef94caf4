#include "lidartag/detector/plane_fit.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace lidartag::detector {
namespace {

Eigen::Vector3d pos(const ClusterPoint& p) {
  return {p.x, p.y, p.z};
}

uint32_t xorshift(uint32_t& s) {
  s ^= s << 13;
  s ^= s >> 17;
  s ^= s << 5;
  return s;
}

}  // namespace

bool fit_plane(std::vector<ClusterPoint>& points, const PlaneOptions& opt, uint32_t seed,
               Plane& plane) {
  plane = Plane{};
  const size_t n = points.size();
  if (n < 3) return false;
  uint32_t s = seed == 0 ? 0x9e3779b9u : seed;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitX();
  double best_d = 0.0;
  int best_count = -1;
  const size_t stride =
      opt.score_points > 0 ? std::max<size_t>(1, n / static_cast<size_t>(opt.score_points)) : 1;
  const float tol = opt.inlier_m;
  // Distances in float (metres to 0.1 micrometre at 40 m is plenty for a 5 cm threshold); the
  // plane through the sample point a, so that the offsets stay small.
  auto inlier = [tol](const ClusterPoint& p, float nx, float ny, float nz, float ax, float ay,
                      float az) {
    return std::fabs(nx * (p.x - ax) + ny * (p.y - ay) + nz * (p.z - az)) <= tol;
  };
  // The adaptive stop: after k hypotheses, all of them drew an outlier with probability
  // (1 - w^3)^k, w the best inlier fraction so far; stop once that is below miss_probability.
  const double scored = static_cast<double>((n + stride - 1) / stride);
  const double log_miss = std::log(static_cast<double>(opt.miss_probability));
  int needed = opt.iterations;
  for (int it = 0; it < needed; ++it) {
    plane.hypotheses = it + 1;
    const Eigen::Vector3d a = pos(points[xorshift(s) % n]);
    const Eigen::Vector3d b = pos(points[xorshift(s) % n]);
    const Eigen::Vector3d c = pos(points[xorshift(s) % n]);
    Eigen::Vector3d nn = (b - a).cross(c - a);
    const double len = nn.norm();
    if (len < 1e-9) continue;
    nn /= len;
    const auto nx = static_cast<float>(nn.x()), ny = static_cast<float>(nn.y()),
               nz = static_cast<float>(nn.z()), ax = static_cast<float>(a.x()),
               ay = static_cast<float>(a.y()), az = static_cast<float>(a.z());
    int count = 0;
    for (size_t k = 0; k < n; k += stride) count += inlier(points[k], nx, ny, nz, ax, ay, az);
    if (count > best_count) {
      best_count = count;
      best_n = nn;
      best_d = -nn.dot(a);
      const double w = count / scored;
      const double all_in = w * w * w;
      // The hypotheses needed, in double (none inlier: -1/0), capped before the conversion.
      const double k = all_in >= 1.0 ? 0.0 : std::ceil(log_miss / std::log1p(-all_in));
      needed =
          all_in > 0.0 ? static_cast<int>(std::min<double>(opt.iterations, k)) : opt.iterations;
    }
  }
  if (best_count < 3) return false;
  // The plane as a unit normal and a point on it, in float, for the inlier tests.
  Eigen::Vector3d on = -best_d * best_n;
  auto inliers_of = [&](const Eigen::Vector3d& nrm, const Eigen::Vector3d& at) {
    return [=, nx = static_cast<float>(nrm.x()), ny = static_cast<float>(nrm.y()),
            nz = static_cast<float>(nrm.z()), ax = static_cast<float>(at.x()),
            ay = static_cast<float>(at.y()), az = static_cast<float>(at.z())](
               const ClusterPoint& p) { return inlier(p, nx, ny, nz, ax, ay, az); };
  };
  // Least squares on the inliers (PCA), then the final inlier set. One pass per refinement: sums
  // of the offsets from a point on the plane (small numbers, no cancellation in double).
  for (int pass = 0; pass < 2; ++pass) {
    const auto is_inlier = inliers_of(best_n, on);
    const auto ox = static_cast<float>(on.x()), oy = static_cast<float>(on.y()),
               oz = static_cast<float>(on.z());
    double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
    int m = 0;
    for (const auto& p : points) {
      if (!is_inlier(p)) continue;
      const double x = p.x - ox, y = p.y - oy, z = p.z - oz;
      sx += x;
      sy += y;
      sz += z;
      sxx += x * x;
      sxy += x * y;
      sxz += x * z;
      syy += y * y;
      syz += y * z;
      szz += z * z;
      ++m;
    }
    if (m < 3) return false;
    const Eigen::Vector3d mo = Eigen::Vector3d(sx, sy, sz) / m;  // mean offset
    Eigen::Matrix3d cov;
    cov << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
    cov = cov / m - mo * mo.transpose();
    const Eigen::Vector3d mean = Eigen::Vector3d(ox, oy, oz) + mo;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    best_n = es.eigenvectors().col(0);
    if (best_n.dot(mean) > 0) best_n = -best_n;  // toward the sensor
    on = mean;
    plane.centroid = mean;
    plane.depth_sigma = std::sqrt(std::max(es.eigenvalues()(0), 0.0));
  }
  plane.normal = best_n;
  const auto is_inlier = inliers_of(best_n, on);
  size_t w = 0;
  for (size_t i = 0; i < n; ++i)
    if (is_inlier(points[i])) points[w++] = points[i];
  plane.inliers = static_cast<int>(w);
  plane.outlier_ratio = 1.0 - static_cast<double>(w) / static_cast<double>(n);
  points.resize(w);
  // The outline (first and last point of each ring) may have changed with the outliers.
  for (size_t i = 0; i < w; ++i)
    points[i].edge = i == 0 || i + 1 == w || points[i - 1].ring != points[i].ring ||
                     points[i + 1].ring != points[i].ring;
  return plane.outlier_ratio <= opt.max_outlier_ratio;
}

}  // namespace lidartag::detector
