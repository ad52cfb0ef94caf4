// Point clouds as other LiDARs' ROS drivers publish them (issue 34 item 3): a rotation of the
// bundled demo capture (VLP-32C, two tag16h5) written as sensor_msgs/PointCloud2 in each driver's
// point layout (field names, types, units and order as in their published point types: Hesai,
// RoboSense, Livox, Ouster, Velodyne), put in a ROS 1 bag and read back through the bag cloud
// reader the tools and Python use. Each must give the tags the detector finds on the rotation
// itself: rings from the ring field (in whichever direction the driver numbers them) or regressed
// from elevations, point times in seconds from the sweep's start whatever unit the driver uses.
// These are the drivers' layouts, not their sensors' scan patterns (the points are a VLP-32C's).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "bag/synthetic_bags.hpp"
#include "lidartag/bag_cloud_reader.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "temp_dir.hpp"

namespace lidartag::clouds {
namespace {

namespace syn = driver::bag::synthetic;

// What a field of a layout holds.
enum class What : uint8_t {
  kX,
  kY,
  kZ,
  kIntensity,
  kRingUp,     // 0 = the lowest beam
  kRingDown,   // 0 = the highest beam (Ouster's drivers)
  kLine,       // Livox's line number: not an elevation order (ring % 4)
  kTimeAbsS,   // seconds since the epoch
  kTimeAbsNs,  // nanoseconds since the epoch, in a double (Livox)
  kTimeRelNs,  // nanoseconds from the sweep's start (Ouster's t)
  kTimeRelS,   // seconds from the sweep's start (Velodyne's time)
  kRange,      // millimetres (Ouster's range)
  kZero,       // a field the detector does not read (tag, ambient, reflectivity)
};

// sensor_msgs/PointField datatypes.
enum Type : uint8_t { kU8 = 2, kU16 = 4, kU32 = 6, kF32 = 7, kF64 = 8 };

struct Field {
  std::string name;
  uint32_t offset;
  Type type;
  What what;
};

struct Layout {
  std::string name;
  uint32_t point_step;
  std::vector<Field> fields;
  bool organized = false;  // rows = beams (top first), every cell written, no return = zeros
  int rings = 0;           // BagCloudOptions::rings: beams to estimate without a ring field
};

// The layouts of the drivers' point types (x, y, z padded to 16 bytes where the type is PCL's
// aligned PointXYZ...).
const std::vector<Layout>& layouts() {
  static const std::vector<Layout> all = {
      {"Hesai (PointXYZIT: intensity float, timestamp double s, ring uint16)",
       48,
       {{"x", 0, kF32, What::kX},
        {"y", 4, kF32, What::kY},
        {"z", 8, kF32, What::kZ},
        {"intensity", 16, kF32, What::kIntensity},
        {"timestamp", 24, kF64, What::kTimeAbsS},
        {"ring", 32, kU16, What::kRingUp}}},
      {"RoboSense (XYZIRT: intensity float, ring uint16, timestamp double s)",
       32,
       {{"x", 0, kF32, What::kX},
        {"y", 4, kF32, What::kY},
        {"z", 8, kF32, What::kZ},
        {"intensity", 16, kF32, What::kIntensity},
        {"ring", 20, kU16, What::kRingUp},
        {"timestamp", 24, kF64, What::kTimeAbsS}}},
      {"Livox (packed: reflectivity float, tag, line uint8, timestamp double ns)",
       26,
       {{"x", 0, kF32, What::kX},
        {"y", 4, kF32, What::kY},
        {"z", 8, kF32, What::kZ},
        {"intensity", 12, kF32, What::kIntensity},
        {"tag", 16, kU8, What::kZero},
        {"line", 17, kU8, What::kLine},
        {"timestamp", 18, kF64, What::kTimeAbsNs}},
       false,
       32},
      {"Ouster (organised beams x columns, t uint32 ns, ring uint16 0 = top, zeros for no return)",
       48,
       {{"x", 0, kF32, What::kX},
        {"y", 4, kF32, What::kY},
        {"z", 8, kF32, What::kZ},
        {"intensity", 16, kF32, What::kIntensity},
        {"t", 20, kU32, What::kTimeRelNs},
        {"reflectivity", 24, kU16, What::kZero},
        {"ring", 26, kU16, What::kRingDown},
        {"ambient", 28, kU16, What::kZero},
        {"range", 32, kU32, What::kRange}},
       true},
      {"Velodyne (XYZIRT: intensity float, ring uint16, time float s from the sweep's start)",
       32,
       {{"x", 0, kF32, What::kX},
        {"y", 4, kF32, What::kY},
        {"z", 8, kF32, What::kZ},
        {"intensity", 16, kF32, What::kIntensity},
        {"ring", 20, kU16, What::kRingUp},
        {"time", 24, kF32, What::kTimeRelS}}},
  };
  return all;
}

template <class T>
void store(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

void write_value(uint8_t* p, Type type, double v) {
  switch (type) {
    case kU8:
      store(p, static_cast<uint8_t>(v));
      break;
    case kU16:
      store(p, static_cast<uint16_t>(v));
      break;
    case kU32:
      store(p, static_cast<uint32_t>(v));
      break;
    case kF32:
      store(p, static_cast<float>(v));
      break;
    case kF64:
      store(p, v);
      break;
  }
}

// One point of the scan (cell i; `valid` false: a no-return cell of an organised cloud, zeros).
void write_point(const Layout& layout, const Scan& scan, size_t i, int ring, bool valid,
                 uint8_t* p) {
  const double t = scan.time_s[i];
  for (const Field& f : layout.fields) {
    double v = 0;
    if (valid) {
      switch (f.what) {
        case What::kX:
          v = scan.x[i];
          break;
        case What::kY:
          v = scan.y[i];
          break;
        case What::kZ:
          v = scan.z[i];
          break;
        case What::kIntensity:
          v = scan.intensity[i];
          break;
        case What::kRingUp:
          v = ring;
          break;
        case What::kRingDown:
          v = scan.rings - 1 - ring;
          break;
        case What::kLine:
          v = ring % 4;
          break;
        case What::kTimeAbsS:
          v = static_cast<double>(scan.stamp_ns) * 1e-9 + t;
          break;
        case What::kTimeAbsNs:
          v = static_cast<double>(scan.stamp_ns) + t * 1e9;
          break;
        case What::kTimeRelNs:
          v = std::round(t * 1e9);
          break;
        case What::kTimeRelS:
          v = t;
          break;
        case What::kRange:
          v = std::round(scan.range[i] * 1000.0);
          break;
        case What::kZero:
          break;
      }
    } else if (f.what == What::kRingDown) {
      v = scan.rings - 1 - ring;  // an organised cloud's empty cells keep their row's ring
    }
    write_value(p + f.offset, f.type, v);
  }
}

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

// The demo's first complete rotation.
bool first_rotation(Scan& out) {
  velodyne::CaptureReader reader(LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap", {});
  while (const Scan* scan = reader.next()) {
    if (!scan->complete) continue;
    out = *scan;
    return true;
  }
  return false;
}

detector::DetectorOptions demo_options() {
  detector::DetectorOptions o;
  o.tag_sizes_m = {0.8, 0.6};
  o.families = {"tag16h5"};
  return o;
}

TEST(VendorClouds, EachDriversLayoutGivesTheTagsOfTheRotationItself) {
  Scan rotation;
  ASSERT_TRUE(first_rotation(rotation));
  detector::Detector detector(demo_options());
  detector::ScanResult direct;
  detector.detect(rotation, direct);
  ASSERT_EQ(direct.detections.size(), 2u);

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
    // Every return is placed (or, binned by azimuth, merged into a cell a nearer point took); an
    // organised cloud's zero cells are no return.
    size_t returns = 0;
    for (int ring = 0; ring < rotation.rings; ++ring)
      for (int col = 0; col < rotation.columns; ++col)
        returns += rotation.valid(rotation.at(0, ring, col)) ? 1u : 0u;
    EXPECT_EQ(reader.report().points + reader.report().merged, returns);
    EXPECT_EQ(reader.report().skipped_coordinates + reader.report().skipped_rings, 0u);
    // Point times: seconds from the sweep's start, within the sweep (0.1 s at 600 rpm).
    double latest = 0;
    for (int ring = 0; ring < scan.rings; ++ring)
      for (int col = 0; col < scan.columns; ++col)
        if (const size_t i = scan.at(0, ring, col); scan.valid(i))
          latest = std::max(latest, double{scan.time_s[i]});
    EXPECT_GT(latest, 0.09);
    EXPECT_LT(latest, 0.11);

    detector::ScanResult got;
    detector.detect(scan, got);
    ASSERT_EQ(got.detections.size(), direct.detections.size());
    for (const auto& want : direct.detections) {
      const auto it = std::find_if(got.detections.begin(), got.detections.end(),
                                   [&](const auto& d) { return d.id == want.id; });
      ASSERT_NE(it, got.detections.end()) << "tag " << want.id;
      EXPECT_LT((it->position - want.position).norm(), 0.02) << "tag " << want.id;
    }
  }
}

}  // namespace
}  // namespace lidartag::clouds
