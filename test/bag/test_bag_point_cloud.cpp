// sensor_msgs/PointCloud2 from a real Luminar bag (ROS 1, lz4 chunks) into the detector's scans:
// fields by name, laser_id as the ring, time_sec + time_nsec as point times; every point counted.
// (The bags README says 5 clouds of 35,707 points: that is the first cloud; the five clouds hold
// 35,707, 36,055, 36,267, 36,457 and 36,336 points, width x height = data / point_step each.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "bag/bag_files.hpp"
#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"

namespace lidartag::driver::bag {
namespace {

using testing::bag;

TEST(BagPointCloud, LuminarCloudsHaveEveryPointAndTheirFields) {
  LIDARTAG_REQUIRE_BAGS();
  ReaderOptions options;
  options.topics = {"/luminar_pointcloud"};
  const auto reader = open_bag(bag("ros1/luminar_pointcloud2_lz4.bag"), options);
  BagMessage m;
  PointCloudView cloud;
  CloudColumns columns;
  const std::vector<size_t> points = {35707, 36055, 36267, 36457, 36336};
  size_t clouds = 0;
  while (reader->next(m)) {
    ASSERT_LT(clouds, points.size());
    const size_t n = points[clouds++];
    ASSERT_EQ(decode_point_cloud(m.data, Encoding::kRos1, cloud), DecodeResult::kOk);
    EXPECT_EQ(cloud.points(), n);
    EXPECT_EQ(cloud.height, 1u);
    EXPECT_EQ(cloud.point_step, 32u);
    EXPECT_EQ(cloud.data.size(), n * 32);
    cloud_columns(cloud, columns);
    EXPECT_EQ(columns.names,
              (std::vector<std::string>{"x", "y", "z", "intensity", "ring", "time"}));
    EXPECT_EQ(columns.source, (std::vector<std::string>{"x", "y", "z", "intensity", "laser_id",
                                                        "time_sec+time_nsec"}));
    for (const auto& c : columns.columns) ASSERT_EQ(c.size(), n);
    // Ring numbers are whole (Luminar's laser_id: its two lasers, 0 and 1), times within a sweep.
    const auto& ring = columns.columns[4];
    const auto& time = columns.columns[5];
    EXPECT_TRUE(std::all_of(ring.begin(), ring.end(), [](double r) { return r == 0 || r == 1; }));
    EXPECT_EQ(*std::min_element(time.begin(), time.end()), 0.0);
    EXPECT_LT(*std::max_element(time.begin(), time.end()), 1.0);

    // Into a scan, as a PCD with a ring field is.
    const detector::CloudFields fields = detector::cloud_fields_by_name(
        columns.names, columns.columns, columns.width, columns.height);
    const detector::CloudScanOptions scan_options =
        detector::cloud_scan_options(fields, {}, 0, 0.2);
    Scan scan;
    const detector::CloudScanReport report = detector::cloud_to_scan(fields, scan_options, scan);
    // Every point is placed, skipped for a named reason, or merged into a taken cell: none lost.
    EXPECT_EQ(report.points + report.skipped_coordinates + report.skipped_rings + report.merged, n);
    EXPECT_GT(report.points, 0u);
    EXPECT_EQ(scan.point_count(), report.points);
    EXPECT_EQ(scan.rings, 2);
  }
  EXPECT_EQ(clouds, 5u);
}

TEST(BagPointCloud, CdrCloudDecodesLikeItsRos1Twin) {
  // A PointCloud2 of 3 points serialized both ways by hand: the same view.
  auto put = [](std::vector<uint8_t>& b, const auto& v) {
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    b.insert(b.end(), p, p + sizeof(v));
  };
  auto pad = [](std::vector<uint8_t>& b, size_t n) {
    while ((b.size() - 4) % n != 0) b.push_back(0);
  };
  const std::vector<std::pair<std::string, uint8_t>> fields = {
      {"x", 7}, {"y", 7}, {"z", 7}, {"intensity", 7}, {"ring", 4}};
  std::vector<uint8_t> data;
  for (int i = 0; i < 3; ++i) {
    const float v[4] = {1.0f + static_cast<float>(i), 2.0f, 3.0f, 40.0f};
    for (const float f : v) put(data, f);
    put(data, static_cast<uint16_t>(i));
    data.push_back(0);
    data.push_back(0);
  }
  std::vector<uint8_t> cdr = {0, 1, 0, 0};
  put(cdr, int32_t{5});
  put(cdr, uint32_t{7});
  put(cdr, uint32_t{4});
  cdr.insert(cdr.end(), {'l', 'd', 'r', 0});
  put(cdr, uint32_t{1});
  put(cdr, uint32_t{3});
  put(cdr, static_cast<uint32_t>(fields.size()));
  uint32_t offset = 0;
  for (const auto& [name, type] : fields) {
    pad(cdr, 4);
    put(cdr, static_cast<uint32_t>(name.size() + 1));
    cdr.insert(cdr.end(), name.begin(), name.end());
    cdr.push_back(0);
    pad(cdr, 4);
    put(cdr, offset);
    cdr.push_back(type);
    pad(cdr, 4);
    put(cdr, uint32_t{1});
    offset += type == 7 ? 4 : 2;
  }
  cdr.push_back(0);  // is_bigendian
  pad(cdr, 4);
  put(cdr, uint32_t{20});
  put(cdr, uint32_t{60});
  put(cdr, static_cast<uint32_t>(data.size()));
  cdr.insert(cdr.end(), data.begin(), data.end());
  cdr.push_back(1);
  PointCloudView view;
  ASSERT_EQ(decode_point_cloud(cdr, Encoding::kCdr, view), DecodeResult::kOk);
  EXPECT_EQ(view.stamp_ns, 5'000'000'007);
  EXPECT_EQ(view.frame_id, "ldr");
  EXPECT_EQ(view.points(), 3u);
  ASSERT_EQ(view.fields.size(), 5u);
  EXPECT_EQ(view.fields[4].name, "ring");
  EXPECT_EQ(view.fields[4].offset, 16u);
  CloudColumns columns;
  cloud_columns(view, columns);
  EXPECT_EQ(columns.columns[0], (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(columns.columns[4], (std::vector<double>{0, 1, 2}));
  // Cut anywhere: truncated, never read past the end.
  for (size_t n = 0; n < cdr.size(); ++n)
    EXPECT_NE(decode_point_cloud(std::span(cdr).first(n), Encoding::kCdr, view), DecodeResult::kOk)
        << n;
}

}  // namespace
}  // namespace lidartag::driver::bag
