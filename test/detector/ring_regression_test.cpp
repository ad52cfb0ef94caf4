// Rings regressed from elevation angles for clouds without ring numbers.
#include "lidartag/detector/ring_regression.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "synthetic_scene.hpp"

namespace lidartag::detector {
namespace {

std::vector<CloudPoint> cloud_of(const Scan& s) {
  std::vector<CloudPoint> c;
  for (int ring = 0; ring < s.rings; ++ring)
    for (int col = 0; col < s.columns; ++col) {
      const size_t i = s.at(0, ring, col);
      if (s.valid(i)) c.push_back({s.x[i], s.y[i], s.z[i], static_cast<float>(s.intensity[i])});
    }
  return c;
}

TEST(RingRegression, EstimatesTheBeamElevations) {
  test::SyntheticScene scene;
  Scan s;
  const auto sensor = test::vlp32c();
  test::render_scene(scene, sensor, s);
  const auto cloud = cloud_of(s);
  const auto e = estimate_elevations(cloud, 32);
  ASSERT_EQ(e.size(), 32u);
  for (size_t k = 0; k < 32; ++k) EXPECT_NEAR(e[k], sensor.elevations_deg[k], 0.01);
  EXPECT_TRUE(estimate_elevations(std::span<const CloudPoint>(cloud).first(10), 32).empty());
}

TEST(RingRegression, RebuildsTheScanFromAnUnorganisedCloud) {
  test::SyntheticScene scene;
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  const auto cloud = cloud_of(s);
  RingRegressionOptions o;
  o.rings = 32;
  Scan out;
  ASSERT_TRUE(regress_rings(cloud, o, out));
  EXPECT_EQ(out.rings, 32);
  EXPECT_EQ(out.columns, 1800);
  EXPECT_EQ(out.point_count(), cloud.size());
  for (int ring = 0; ring < 32; ++ring)
    for (int col = 0; col < 1800; col += 7) {
      const size_t i = s.at(0, ring, col), j = out.at(0, ring, col);
      EXPECT_EQ(s.valid(i), out.valid(j));
      if (s.valid(i)) {
        EXPECT_FLOAT_EQ(s.x[i], out.x[j]);
      }
    }
  RingRegressionOptions none;
  EXPECT_FALSE(regress_rings(cloud, none, out));
}

TEST(RingRegression, OrganisesACloudThatCarriesItsRings) {
  test::SyntheticScene scene;
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  auto cloud = cloud_of(s);
  // Give every point its true ring; a few points with rings outside the sensor are dropped.
  size_t k = 0;
  for (int ring = 0; ring < s.rings; ++ring)
    for (int col = 0; col < s.columns; ++col)
      if (s.valid(s.at(0, ring, col))) cloud[k++].ring = ring;
  cloud.push_back({5.0f, 0.0f, 0.0f, 10.0f, 32});
  cloud.push_back({5.0f, 1.0f, 0.0f, 10.0f, -1});
  Scan out;
  ASSERT_TRUE(organise_rings(cloud, 32, 0.2, out));
  EXPECT_EQ(out.rings, 32);
  EXPECT_EQ(out.columns, 1800);
  EXPECT_EQ(out.point_count(), cloud.size() - 2);
  for (int ring = 0; ring < 32; ++ring)
    for (int col = 0; col < 1800; col += 7) {
      const size_t i = s.at(0, ring, col), j = out.at(0, ring, col);
      ASSERT_EQ(s.valid(i), out.valid(j));
      if (s.valid(i)) {
        EXPECT_FLOAT_EQ(s.z[i], out.z[j]);
      }
    }
  EXPECT_FALSE(organise_rings(cloud, 0, 0.2, out));
  EXPECT_FALSE(organise_rings(cloud, 32, 0.0, out));
}

TEST(RingRegression, NonFinitePointsAreSkippedAndNanIntensityReadsAsZero) {
  test::SyntheticScene scene;
  Scan s;
  test::render_scene(scene, test::vlp32c(), s);
  auto cloud = cloud_of(s);
  const size_t clean = cloud.size();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (size_t k = 0; k < clean; k += 7) cloud[k].intensity = nan;
  for (size_t k = 0; k < 200; ++k) {
    cloud.push_back({nan, 1.0f, 0.5f, 10.0f});
    cloud.push_back({1.0f, inf, 0.5f, 10.0f});
    cloud.push_back({nan, nan, nan, nan});
    cloud.push_back({0.0f, 0.0f, 0.0f, 10.0f});
    cloud.push_back({3.0f, 1.0f, -0.2f, -inf, static_cast<int>(k) - 100});  // ring out of range
  }
  // The elevations come from the finite points only.
  const auto e = estimate_elevations(cloud, 32);
  ASSERT_EQ(e.size(), 32u);
  for (double v : e) EXPECT_TRUE(std::isfinite(v));
  RingRegressionOptions o;
  o.rings = 32;
  Scan out;
  ASSERT_TRUE(regress_rings(cloud, o, out));
  size_t valid = 0;
  for (int ring = 0; ring < out.rings; ++ring)
    for (int col = 0; col < out.columns; ++col) {
      const size_t i = out.at(0, ring, col);
      if (!out.valid(i)) continue;
      ++valid;
      ASSERT_TRUE(std::isfinite(out.x[i]) && std::isfinite(out.y[i]) && std::isfinite(out.z[i]));
      ASSERT_TRUE(std::isfinite(out.range[i]));
    }
  EXPECT_GE(valid, clean * 9 / 10);
  // Rings from the points: those outside [0, rings) are dropped, the others placed.
  ASSERT_TRUE(organise_rings(cloud, 32, 0.2, out));
  EXPECT_LE(out.point_count(), 100u);
  // Elevations that are not numbers are refused, not sorted.
  o.elevations_deg = {-10.0, std::numeric_limits<double>::quiet_NaN(), 5.0};
  EXPECT_FALSE(regress_rings(cloud, o, out));
}

TEST(RingRegression, AbsurdResolutionIsRefused) {
  const std::vector<CloudPoint> cloud = {{5.0f, 0.0f, 0.0f, 10.0f, 0},
                                         {5.0f, 0.1f, 0.5f, 10.0f, 1}};
  Scan out;
  for (double res : {0.0, -1.0, 1e-300, 1e-9, 361.0, std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity()}) {
    EXPECT_FALSE(organise_rings(cloud, 2, res, out)) << res;
    RingRegressionOptions o;
    o.elevations_deg = {0.0, 5.7};
    o.horizontal_resolution_deg = res;
    EXPECT_FALSE(regress_rings(cloud, o, out)) << res;
  }
  EXPECT_TRUE(organise_rings(cloud, 2, 0.2, out));
  EXPECT_EQ(out.point_count(), 2u);
}

}  // namespace
}  // namespace lidartag::detector
