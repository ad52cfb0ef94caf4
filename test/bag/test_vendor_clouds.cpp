// Point clouds as other LiDARs' ROS drivers publish them (issue 34 item 3): a rotation of the
// bundled demo capture (VLP-32C, two tag16h5) written as sensor_msgs/PointCloud2 in each driver's
// point layout (field names, types, units and order as in their published point types: Hesai,
// RoboSense, Livox, Ouster, Velodyne), put in a ROS 1 bag and read back through the bag cloud
// reader the tools and Python use. Each must give the tags the detector finds on the rotation
// itself: rings from the ring field (in whichever direction the driver numbers them) or regressed
// from elevations (no ring field, or one whose rings are not level: Livox's lines), point times in
// seconds from the sweep's start whatever unit the driver uses. These are the drivers' layouts, not
// their sensors' scan patterns (the points are a VLP-32C's).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "bag/synthetic_bags.hpp"
#include "bag/vendor_layouts.hpp"
#include "lidartag/bag_cloud_reader.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "temp_dir.hpp"

namespace lidartag::clouds {
namespace {

namespace syn = driver::bag::synthetic;

// sensor_msgs/PointCloud2, ROS 1 serialisation, of the scan's first return in `layout`.
syn::Bytes cloud_message(const Layout& layout, const Scan& scan) {
  std::vector<uint8_t> data;
  uint32_t width = 0, height = 1;
  if (layout.organized) {
    height = static_cast<uint32_t>(scan.rings);
    width = static_cast<uint32_t>(scan.columns);
    data.assign(size_t{height} * width * layout.point_step, 0);
    for (int row = 0; row < scan.rings; ++row) {
      const int ring = scan.rings - 1 - row;  // row 0: the top beam
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(0, ring, col);
        write_point(layout, scan, i, ring, scan.valid(i),
                    data.data() + (size_t(row) * width + size_t(col)) * layout.point_step);
      }
    }
  } else {
    for (int col = 0; col < scan.columns; ++col) {  // firing order, as the drivers publish
      for (int ring = 0; ring < scan.rings; ++ring) {
        const size_t i = scan.at(0, ring, col);
        if (!scan.valid(i)) continue;
        data.resize(data.size() + layout.point_step);
        write_point(layout, scan, i, ring, true, data.data() + data.size() - layout.point_step);
        ++width;
      }
    }
  }
  syn::Bytes b;
  syn::ros1_header(b, scan.stamp_ns, "lidar");
  syn::put(b, height);
  syn::put(b, width);
  syn::put(b, static_cast<uint32_t>(layout.fields.size()));
  for (const Field& f : layout.fields) {
    syn::put(b, static_cast<uint32_t>(f.name.size()));
    syn::put(b, std::string_view(f.name));
    syn::put(b, f.offset);
    syn::put(b, static_cast<uint8_t>(f.type));
    syn::put(b, uint32_t{1});
  }
  syn::put(b, uint8_t{0});  // is_bigendian
  syn::put(b, layout.point_step);
  syn::put(b, layout.point_step * width);
  syn::put(b, static_cast<uint32_t>(data.size()));
  syn::put(b, data.data(), data.size());
  syn::put(b, uint8_t{layout.organized ? uint8_t{0} : uint8_t{1}});  // is_dense
  return b;
}

using VendorClouds = DemoRotation;

TEST_F(VendorClouds, EachDriversLayoutGivesTheTagsOfTheRotationItself) {
  test::ProcessTempDir dir("vendor_clouds");
  for (const Layout& layout : layouts()) {
    SCOPED_TRACE(layout.name);
    const std::string path = dir.path() + "/cloud.bag";
    const syn::Bytes bag =
        syn::ros1_bag({{"/points", "sensor_msgs/PointCloud2"}},
                      {{{"/points", rotation.stamp_ns, cloud_message(layout, rotation)}}});
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bag.data()), static_cast<std::streamsize>(bag.size()));

    BagCloudOptions options;
    options.rings = layout.rings;
    BagCloudReader reader(path, options);
    Scan scan;
    ASSERT_EQ(reader.next(scan), BagCloudReader::Step::kScan) << reader.problem();
    EXPECT_EQ(scan.rings, rotation.rings);
    EXPECT_EQ(reader.report().regressed, layout.rings > 0);
    // Livox's line numbers are read as its ring field, found not level and set aside.
    EXPECT_EQ(reader.report().rings_not_level, layout.rings > 0);
    // Every return is placed (or, binned by azimuth, merged into a cell a nearer point took); an
    // organised cloud's zero cells are no return.
    size_t returns = 0;
    for (int ring = 0; ring < rotation.rings; ++ring)
      for (int col = 0; col < rotation.columns; ++col)
        returns += rotation.valid(rotation.at(0, ring, col)) ? 1u : 0u;
    EXPECT_EQ(reader.report().points + reader.report().merged, returns);
    EXPECT_EQ(reader.report().skipped_coordinates + reader.report().skipped_rings, 0u);
    expect_sweep_times_and_the_rotations_tags(detector, scan, direct);
  }
}

}  // namespace
}  // namespace lidartag::clouds
