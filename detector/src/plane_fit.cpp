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
  for (int it = 0; it < opt.iterations; ++it) {
    const Eigen::Vector3d a = pos(points[xorshift(s) % n]);
    const Eigen::Vector3d b = pos(points[xorshift(s) % n]);
    const Eigen::Vector3d c = pos(points[xorshift(s) % n]);
    Eigen::Vector3d nn = (b - a).cross(c - a);
    const double len = nn.norm();
    if (len < 1e-9) continue;
    nn /= len;
    const double d = -nn.dot(a);
    int count = 0;
    for (size_t k = 0; k < n; k += stride)
      count += std::fabs(nn.dot(pos(points[k])) + d) <= opt.inlier_m ? 1 : 0;
    if (count > best_count) {
      best_count = count;
      best_n = nn;
      best_d = d;
    }
  }
  if (best_count < 3) return false;
  // Least squares on the inliers (PCA), then the final inlier set.
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int m = 0;
    for (const auto& p : points)
      if (std::fabs(best_n.dot(pos(p)) + best_d) <= opt.inlier_m) {
        mean += pos(p);
        ++m;
      }
    if (m < 3) return false;
    mean /= m;
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points)
      if (std::fabs(best_n.dot(pos(p)) + best_d) <= opt.inlier_m) {
        const Eigen::Vector3d q = pos(p) - mean;
        cov += q * q.transpose();
      }
    cov /= m;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    best_n = es.eigenvectors().col(0);
    if (best_n.dot(mean) > 0) best_n = -best_n;  // toward the sensor
    best_d = -best_n.dot(mean);
    plane.centroid = mean;
    plane.depth_sigma = std::sqrt(std::max(es.eigenvalues()(0), 0.0));
  }
  plane.normal = best_n;
  size_t w = 0;
  for (size_t i = 0; i < n; ++i)
    if (std::fabs(best_n.dot(pos(points[i])) + best_d) <= opt.inlier_m) points[w++] = points[i];
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
