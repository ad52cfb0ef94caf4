// Stage 3: RANSAC plane fit and the outlier ratio kappa.
#include "lidartag/detector/plane_fit.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace lidartag::detector {
namespace {

std::vector<ClusterPoint> noisy_plane(int n, double outlier_fraction, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  std::normal_distribution<double> noise(0.0, 0.01);
  // Plane through (7, 1, 0) with normal (-1, -1, 0.2) normalised.
  const Eigen::Vector3d c(7, 1, 0), nrm = Eigen::Vector3d(-1, -1, 0.2).normalized();
  const Eigen::Vector3d a = nrm.cross(Eigen::Vector3d::UnitZ()).normalized(), b = nrm.cross(a);
  std::vector<ClusterPoint> pts;
  for (int i = 0; i < n; ++i) {
    const bool out = i < static_cast<int>(outlier_fraction * n);
    const Eigen::Vector3d p = c + u(rng) * a + u(rng) * b + (out ? 0.5 + u(rng) : noise(rng)) * nrm;
    ClusterPoint q;
    q.x = static_cast<float>(p.x());
    q.y = static_cast<float>(p.y());
    q.z = static_cast<float>(p.z());
    q.ring = i / 20;
    pts.push_back(q);
  }
  return pts;
}

TEST(PlaneFit, FindsTheNormalAndDropsOutliers) {
  auto pts = noisy_plane(400, 0.05, 3);
  Plane pl;
  ASSERT_TRUE(fit_plane(pts, PlaneOptions{}, 7, pl));
  const Eigen::Vector3d truth = Eigen::Vector3d(-1, -1, 0.2).normalized();
  EXPECT_GT(pl.normal.dot(truth), 0.999);  // oriented toward the sensor
  EXPECT_NEAR(pl.outlier_ratio, 0.05, 0.01);
  EXPECT_EQ(pts.size(), static_cast<size_t>(pl.inliers));
  EXPECT_NEAR(pl.depth_sigma, 0.01, 0.003);
}

TEST(PlaneFit, RejectsWhenOutliersExceedKappa) {
  auto pts = noisy_plane(400, 0.3, 4);
  Plane pl;
  EXPECT_FALSE(fit_plane(pts, PlaneOptions{}, 7, pl));
  EXPECT_NEAR(pl.outlier_ratio, 0.3, 0.03);
  auto again = noisy_plane(400, 0.3, 4);
  PlaneOptions outdoor;
  outdoor.max_outlier_ratio = 0.35f;
  EXPECT_TRUE(fit_plane(again, outdoor, 7, pl));
}

// The adaptive stop: a clear plane needs few hypotheses, one with many outliers all of them, and
// the plane found is the one that many more hypotheses give.
TEST(PlaneFit, AClearPlaneStopsDrawingHypothesesEarlyWithTheSamePlane) {
  PlaneOptions more;
  more.miss_probability = 1e-30f;
  for (double outliers : {0.0, 0.02, 0.1}) {
    auto pts = noisy_plane(400, outliers, 5);
    auto again = pts;
    Plane adaptive, full;
    ASSERT_TRUE(fit_plane(pts, PlaneOptions{}, 7, adaptive));
    ASSERT_TRUE(fit_plane(again, more, 7, full));
    EXPECT_GE(full.hypotheses, adaptive.hypotheses);
    // 1e-9 at the inlier fraction found: 6 hypotheses at 99 %, 16 at 90 %.
    EXPECT_LE(adaptive.hypotheses, outliers < 0.05 ? 8 : 20) << outliers;
    EXPECT_GT(adaptive.normal.dot(full.normal), 0.99999) << outliers;
    EXPECT_NEAR((adaptive.centroid - full.centroid).norm(), 0.0, 1e-4) << outliers;
    EXPECT_EQ(adaptive.inliers, full.inliers) << outliers;
  }
  auto many = noisy_plane(400, 0.35, 6);  // 65 % inliers: 1e-9 needs more than 40
  Plane pl;
  fit_plane(many, PlaneOptions{}, 7, pl);
  EXPECT_EQ(pl.hypotheses, PlaneOptions{}.iterations);
}

TEST(PlaneFit, TooFewPointsFail) {
  std::vector<ClusterPoint> two(2);
  Plane pl;
  EXPECT_FALSE(fit_plane(two, PlaneOptions{}, 1, pl));
}

}  // namespace
}  // namespace lidartag::detector
