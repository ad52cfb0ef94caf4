#include "lidartag/daemon/decimated_cloud.hpp"

#include <gtest/gtest.h>

namespace lidartag::daemon {
namespace {

Scan filled(int rings, int returns, int capacity, int columns) {
  Scan s;
  s.reserve(rings, returns, capacity);
  s.columns = columns;
  for (int r = 0; r < returns; ++r)
    for (int ring = 0; ring < rings; ++ring)
      for (int c = 0; c < columns; ++c) {
        const size_t i = s.at(r, ring, c);
        const float v = static_cast<float>(r * 10000 + ring * 100 + c);
        s.x[i] = v;
        s.y[i] = -v;
        s.z[i] = v * 0.5f;
        s.range[i] = v + 1;
        s.azimuth_deg[i] = static_cast<float>(c);
        s.time_s[i] = v * 1e-6f;
        s.intensity[i] = static_cast<uint8_t>(c % 256);
        s.return_type[i] = ReturnType::kStrongest;
      }
  for (int ring = 0; ring < rings; ++ring) {
    s.laser_id[static_cast<size_t>(ring)] = static_cast<uint8_t>(rings - 1 - ring);
  }
  for (int c = 0; c < columns; ++c) {
    s.column_azimuth_deg[static_cast<size_t>(c)] = static_cast<float>(c) * 0.2f;
    s.column_time_s[static_cast<size_t>(c)] = c * 5e-5;
  }
  s.sequence = 42;
  s.stamp_ns = 1700000000000000000;
  s.complete = true;
  s.rpm = 600;
  s.packets = 7;
  return s;
}

TEST(DecimatedCloud, HoldsTheReturnsOfEveryKthColumnInOrder) {
  Scan src = filled(4, 2, 50, 30);
  // Cells without a return are left out.
  src.range[src.at(0, 1, 3)] = 0;
  for (int ring = 0; ring < 4; ++ring) src.range[src.at(1, ring, 6)] = 0;
  DecimatedCloud cloud;
  for (int k : {1, 3, 7, 29, 30, 40}) {
    SCOPED_TRACE(k);
    decimate_scan(src, k, cloud);
    EXPECT_EQ(cloud.decimation, k);
    EXPECT_EQ(cloud.columns, (30 + k - 1) / k);
    size_t n = 0;
    for (int c = 0; c < 30; c += k)
      for (int r = 0; r < 2; ++r)
        for (int ring = 0; ring < 4; ++ring) {
          const size_t i = src.at(r, ring, c);
          if (src.range[i] == 0) continue;
          ASSERT_LT(n, cloud.size());
          EXPECT_EQ(cloud.x[n], src.x[i]);
          EXPECT_EQ(cloud.y[n], src.y[i]);
          EXPECT_EQ(cloud.z[n], src.z[i]);
          EXPECT_EQ(cloud.intensity[n], src.intensity[i]);
          EXPECT_EQ(cloud.ring[n], ring);
          ++n;
        }
    EXPECT_EQ(cloud.size(), n);
    for (const auto* v : {&cloud.y, &cloud.z}) EXPECT_EQ(v->size(), n);
    EXPECT_EQ(cloud.intensity.size(), n);
    EXPECT_EQ(cloud.ring.size(), n);
  }
  decimate_scan(src, 1, cloud);
  EXPECT_EQ(cloud.size(), src.point_count());
  EXPECT_EQ(cloud.size(), 4u * 2u * 30u - 1u - 4u);
  // Reused: the next rotation fills the same storage.
  const float* storage = cloud.x.data();
  decimate_scan(src, 2, cloud);
  decimate_scan(src, 1, cloud);
  EXPECT_EQ(cloud.x.data(), storage);
  // Off: nothing.
  decimate_scan(src, 0, cloud);
  EXPECT_EQ(cloud.size(), 0u);
  EXPECT_EQ(cloud.columns, 0);
  decimate_scan(Scan{}, 4, cloud);
  EXPECT_EQ(cloud.size(), 0u);
  EXPECT_EQ(cloud.columns, 0);
}

}  // namespace
}  // namespace lidartag::daemon
