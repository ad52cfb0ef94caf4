// Point layouts of other LiDARs' ROS drivers (issue 34 item 3), shared by the tests that write a
// rotation of the bundled demo capture in them: as sensor_msgs/PointCloud2 in a bag
// (test_vendor_clouds) and as PCD files, as pcl_ros and the vendors' tools save those clouds
// (test_vendor_pcds). Field names, types, units and order as in the drivers' published point
// types; the points are a VLP-32C's, not the sensors' scan patterns.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::clouds {

// What a field of a layout holds.
enum class What : uint8_t {
  kX,
  kY,
  kZ,
  kIntensity,
  kRingUp,     // 0 = the lowest beam
  kRingDown,   // 0 = the highest beam (Ouster's drivers)
  kLine,       // Livox's line number: its lines are not rings of one elevation (ring % 4)
  kTimeAbsS,   // seconds since the epoch
  kTimeAbsNs,  // nanoseconds since the epoch, in a double (Livox)
  kTimeRelNs,  // nanoseconds from the sweep's start (Ouster's t)
  kTimeRelS,   // seconds from the sweep's start (Velodyne's time)
  kRange,      // millimetres (Ouster's range)
  kZero,       // a field the detector does not read (tag, ambient, reflectivity)
};

// sensor_msgs/PointField datatypes.
enum Type : uint8_t {
  kI8 = 1,
  kU8 = 2,
  kI16 = 3,
  kU16 = 4,
  kI32 = 5,
  kU32 = 6,
  kF32 = 7,
  kF64 = 8
};

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
inline const std::vector<Layout>& layouts() {
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
      {"Integer types (x y z double, intensity uint8, channel int16, time_offset int32 ns)",
       32,
       {{"x", 0, kF64, What::kX},
        {"y", 8, kF64, What::kY},
        {"z", 16, kF64, What::kZ},
        {"intensity", 24, kU8, What::kIntensity},
        {"tag", 25, kI8, What::kZero},
        {"channel", 26, kI16, What::kRingUp},
        {"time_offset", 28, kI32, What::kTimeRelNs}}},
  };
  return all;
}

template <class T>
void store(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

inline void write_value(uint8_t* p, Type type, double v) {
  switch (type) {
    case kI8:
      store(p, static_cast<int8_t>(v));
      break;
    case kU8:
      store(p, static_cast<uint8_t>(v));
      break;
    case kI16:
      store(p, static_cast<int16_t>(v));
      break;
    case kI32:
      store(p, static_cast<int32_t>(v));
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
inline void write_point(const Layout& layout, const Scan& scan, size_t i, int ring, bool valid,
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

// The demo's first complete rotation.
inline bool first_rotation(Scan& out) {
  velodyne::CaptureReader reader(LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap", {});
  while (const Scan* scan = reader.next()) {
    if (!scan->complete) continue;
    out = *scan;
    return true;
  }
  return false;
}

inline detector::DetectorOptions demo_options() {
  detector::DetectorOptions o;
  o.tag_sizes_m = {0.8, 0.6};
  o.families = {"tag16h5"};
  return o;
}

// The demo's first complete rotation and its two tags as the detector finds them on the rotation
// itself: what every vendor layout of that rotation is checked against.
class DemoRotation : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(first_rotation(rotation));
    detector.detect(rotation, direct);
    ASSERT_EQ(direct.detections.size(), 2u);
  }

  Scan rotation;
  detector::Detector detector{demo_options()};
  detector::ScanResult direct;
};

// What both tests ask of a vendor cloud read back as `scan`: point times in seconds from the
// sweep's start, within the sweep (0.1 s at 600 rpm), and every tag of the rotation's own
// detections (`direct`) found by `detector` within 2 cm, and no other.
inline void expect_sweep_times_and_the_rotations_tags(detector::Detector& detector,
                                                      const Scan& scan,
                                                      const detector::ScanResult& direct) {
  double latest = 0;
  for (size_t i = 0; i < scan.range.size(); ++i)
    if (scan.valid(i)) latest = std::max(latest, double{scan.time_s[i]});
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

}  // namespace lidartag::clouds
