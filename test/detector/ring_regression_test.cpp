// Rings regressed from elevation angles for clouds without ring numbers.
#include "lidartag/detector/ring_regression.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace lidartag::detector
