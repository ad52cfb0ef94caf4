// PCD files as other LiDARs' ROS tools save their clouds (issue 34 item 3): a rotation of the
// bundled demo capture written in each driver's point layout (vendor_layouts.hpp: Hesai PointXYZIT,
// RoboSense XYZIRT, Livox with `line`, Ouster organised with `t` and `ring`, Velodyne, integer
// types) as pcl_ros's pointcloud_to_pcd writes a PointCloud2: every field by its name, the gaps
// between fields as PCL's `_` padding fields (COUNT > 1), organised clouds WIDTH x HEIGHT with NaN
// for no return; in each of DATA binary, binary_compressed and ascii. Each is read as the tools and
// Python read a PCD (read_pcd, pcd_cloud_columns: the field vocabulary bags share) and must give
// every return and the tags the detector finds on the rotation itself, within 2 cm; one of them
// also through `lidartag detect`. Also: each driver's time unit into seconds (the shared rule) and
// ring fields out of range (counted, or a clear error when no point has a ring).
#include <gtest/gtest.h>
#include <lzf.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bag/vendor_layouts.hpp"
#include "lidartag/detector/cloud_scan.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "lidartag/pcd_scan.hpp"
#include "temp_dir.hpp"
#include "tools/run_tool.hpp"

namespace lidartag::clouds {
namespace {

// A PCD field: one of the layout's, or `_` padding of `count` bytes.
struct PcdField {
  std::string name;
  char type = 'U';
  size_t size = 1, count = 1;
  uint32_t offset = 0;
};

PcdField pcd_field(const Field& f) {
  switch (f.type) {
    case kI8:
      return {f.name, 'I', 1, 1, f.offset};
    case kU8:
      return {f.name, 'U', 1, 1, f.offset};
    case kI16:
      return {f.name, 'I', 2, 1, f.offset};
    case kU16:
      return {f.name, 'U', 2, 1, f.offset};
    case kI32:
      return {f.name, 'I', 4, 1, f.offset};
    case kU32:
      return {f.name, 'U', 4, 1, f.offset};
    case kF32:
      return {f.name, 'F', 4, 1, f.offset};
    case kF64:
      break;
  }
  return {f.name, 'F', 8, 1, f.offset};
}

// The layout's fields in offset order, the gaps (and the tail up to point_step) as `_` padding.
std::vector<PcdField> pcd_fields(const Layout& layout) {
  std::vector<Field> fields = layout.fields;
  std::sort(fields.begin(), fields.end(),
            [](const Field& a, const Field& b) { return a.offset < b.offset; });
  std::vector<PcdField> out;
  uint32_t at = 0;
  for (const Field& f : fields) {
    if (f.offset > at) out.push_back({"_", 'U', 1, f.offset - at, at});
    out.push_back(pcd_field(f));
    at = f.offset + static_cast<uint32_t>(out.back().size);
  }
  if (layout.point_step > at) out.push_back({"_", 'U', 1, layout.point_step - at, at});
  return out;
}

template <class T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

void append_text(std::string& out, const uint8_t* p, const PcdField& f) {
  char buffer[64];
  std::to_chars_result r{};
  if (f.type == 'F' && f.size == 4) {
    r = std::to_chars(buffer, buffer + sizeof(buffer), load<float>(p));
  } else if (f.type == 'F') {
    r = std::to_chars(buffer, buffer + sizeof(buffer), load<double>(p));
  } else if (f.type == 'U') {
    const uint64_t v = f.size == 1   ? load<uint8_t>(p)
                       : f.size == 2 ? load<uint16_t>(p)
                                     : load<uint32_t>(p);
    r = std::to_chars(buffer, buffer + sizeof(buffer), v);
  } else {
    const int64_t v = f.size == 1   ? load<int8_t>(p)
                      : f.size == 2 ? load<int16_t>(p)
                                    : load<int32_t>(p);
    r = std::to_chars(buffer, buffer + sizeof(buffer), v);
  }
  out.append(buffer, r.ptr);
}

// The scan's first return in `layout` as a PCD file; returns the number of points written.
size_t write_vendor_pcd(const std::string& path, const Layout& layout, const Scan& scan,
                        velodyne::PcdFormat format) {
  std::vector<uint8_t> data;  // point_step bytes a point, as the PointCloud2 holds them
  size_t width = 0, height = 1;
  const auto point = [&]() {
    data.resize(data.size() + layout.point_step, 0);
    return data.data() + data.size() - layout.point_step;
  };
  if (layout.organized) {
    height = static_cast<size_t>(scan.rings);
    width = static_cast<size_t>(scan.columns);
    for (int row = 0; row < scan.rings; ++row) {
      const int ring = scan.rings - 1 - row;  // row 0: the top beam
      for (int col = 0; col < scan.columns; ++col) {
        const size_t i = scan.at(0, ring, col);
        uint8_t* p = point();
        write_point(layout, scan, i, ring, scan.valid(i), p);
        if (scan.valid(i)) continue;
        // No return: NaN coordinates, as PCL's organised clouds have them.
        for (const Field& f : layout.fields)
          if (f.what == What::kX || f.what == What::kY || f.what == What::kZ)
            write_value(p + f.offset, f.type, std::numeric_limits<double>::quiet_NaN());
      }
    }
  } else {
    for (int col = 0; col < scan.columns; ++col) {
      for (int ring = 0; ring < scan.rings; ++ring) {
        const size_t i = scan.at(0, ring, col);
        if (!scan.valid(i)) continue;
        write_point(layout, scan, i, ring, true, point());
        ++width;
      }
    }
  }
  const size_t n = width * height;
  const std::vector<PcdField> fields = pcd_fields(layout);
  std::ostringstream header;
  header << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS";
  for (const auto& f : fields) header << ' ' << f.name;
  header << "\nSIZE";
  for (const auto& f : fields) header << ' ' << f.size;
  header << "\nTYPE";
  for (const auto& f : fields) header << ' ' << f.type;
  header << "\nCOUNT";
  for (const auto& f : fields) header << ' ' << f.count;
  header << "\nWIDTH " << width << "\nHEIGHT " << height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS "
         << n << "\nDATA " << velodyne::pcd_format_name(format) << "\n";
  std::string body;
  if (format == velodyne::PcdFormat::kBinary) {
    body.assign(reinterpret_cast<const char*>(data.data()), data.size());
  } else if (format == velodyne::PcdFormat::kAscii) {
    for (size_t k = 0; k < n; ++k) {
      const uint8_t* p = data.data() + k * layout.point_step;
      for (const auto& f : fields) {
        for (size_t c = 0; c < f.count; ++c) {
          append_text(body, p + f.offset + c * f.size, f);
          body += ' ';
        }
      }
      body.back() = '\n';
    }
  } else {
    // Field by field, each of every point in turn, LZF-compressed behind the two sizes.
    std::string plain;
    for (const auto& f : fields)
      for (size_t k = 0; k < n; ++k)
        plain.append(reinterpret_cast<const char*>(data.data() + k * layout.point_step + f.offset),
                     f.size * f.count);
    std::string packed(plain.size() + plain.size() / 16 + 64, '\0');
    const unsigned got = lzf_compress(plain.data(), static_cast<unsigned>(plain.size()),
                                      packed.data(), static_cast<unsigned>(packed.size()));
    EXPECT_GT(got, 0u);
    const auto sizes = std::array<uint32_t, 2>{got, static_cast<uint32_t>(plain.size())};
    body.assign(reinterpret_cast<const char*>(sizes.data()), 8);
    body.append(packed.data(), got);
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << header.str();
  out.write(body.data(), static_cast<std::streamsize>(body.size()));
  return n;
}

size_t first_returns(const Scan& rotation) {
  size_t returns = 0;
  for (int ring = 0; ring < rotation.rings; ++ring)
    for (int col = 0; col < rotation.columns; ++col)
      returns += rotation.valid(rotation.at(0, ring, col)) ? 1u : 0u;
  return returns;
}

constexpr velodyne::PcdFormat kFormats[] = {velodyne::PcdFormat::kBinary,
                                            velodyne::PcdFormat::kBinaryCompressed,
                                            velodyne::PcdFormat::kAscii};

using VendorPcdsOfTheDemo = DemoRotation;

TEST_F(VendorPcdsOfTheDemo, EachDriversLayoutInEachDataKindGivesTheTagsOfTheRotationItself) {
  const size_t returns = first_returns(rotation);

  test::ProcessTempDir dir("vendor_pcds");
  for (const Layout& layout : layouts()) {
    for (const velodyne::PcdFormat format : kFormats) {
      SCOPED_TRACE(layout.name + ", DATA " + std::string(velodyne::pcd_format_name(format)));
      const std::string path = dir.path() + "/cloud.pcd";
      const size_t written = write_vendor_pcd(path, layout, rotation, format);

      const velodyne::PcdCloud pcd = velodyne::read_pcd_points(path);
      ASSERT_EQ(pcd.size(), written);
      EXPECT_EQ(pcd.format, format);
      driver::CloudColumns columns;
      velodyne::pcd_cloud_columns(pcd, columns);
      for (const char* name : {"x", "y", "z", "intensity", "time"})
        EXPECT_NE(std::find(columns.names.begin(), columns.names.end(), name), columns.names.end())
            << name;
      // The conversion the tools and Python run (pcd_scan.hpp).
      Scan scan;
      const PcdScan read = read_pcd_scan(path, std::nullopt, layout.rings, 0.2, scan);
      EXPECT_FALSE(read.ring_field.empty());  // every layout has a ring field of some name
      EXPECT_EQ(read.file_points, written);
      const detector::CloudScanReport& report = read.report;
      EXPECT_EQ(scan.rings, rotation.rings);
      EXPECT_EQ(report.regressed, layout.rings > 0);  // Livox's lines are not rings
      EXPECT_EQ(report.rings_not_level, layout.rings > 0);
      EXPECT_EQ(report.grid, layout.organized);
      // Every return in place (binned by azimuth: or merged into a cell a nearer point took).
      EXPECT_EQ(report.points + report.merged, returns);
      EXPECT_EQ(report.skipped_coordinates + report.skipped_rings, 0u);
      if (!layout.organized) {
        EXPECT_EQ(written, returns);
      }
      expect_sweep_times_and_the_rotations_tags(detector, scan, direct);
    }
  }
}

const Layout& layout_named(const std::string& prefix) {
  for (const Layout& l : layouts())
    if (l.name.rfind(prefix, 0) == 0) return l;
  throw std::runtime_error("no layout " + prefix);
}

TEST_F(VendorPcdsOfTheDemo, LidartagDetectReadsAHesaiPcd) {
  test::ProcessTempDir dir("vendor_pcds_cli");
  const std::string path = dir.path() + "/hesai.pcd";
  write_vendor_pcd(path, layout_named("Hesai"), rotation, velodyne::PcdFormat::kBinaryCompressed);
  const auto r = testing::run_tool("detect --json --tag-size 0.8 --tag-size 0.6 " + path, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto json = nlohmann::json::parse(r.out.substr(0, r.out.find('\n')));
  // Binned by azimuth: a few neighbours share a 0.2 degree column.
  const auto points = json["points"].get<size_t>();
  EXPECT_LE(points, first_returns(rotation));
  EXPECT_GT(points, first_returns(rotation) * 98 / 100);
  ASSERT_EQ(json["detections"].size(), direct.detections.size()) << r.out;
  for (const auto& want : direct.detections) {
    bool found = false;
    for (const auto& d : json["detections"]) {
      if (d["id"].get<int>() != want.id) continue;
      found = true;
      const auto p = d["position"].get<std::vector<double>>();
      EXPECT_LT(
          std::hypot(p[0] - want.position.x(), p[1] - want.position.y(), p[2] - want.position.z()),
          0.02)
          << "tag " << want.id;
    }
    EXPECT_TRUE(found) << "tag " << want.id << ": " << r.out;
  }

  // Livox's lines are not rings: without --rings the tool says how to regress them.
  const std::string livox = dir.path() + "/livox.pcd";
  write_vendor_pcd(livox, layout_named("Livox"), rotation, velodyne::PcdFormat::kAscii);
  auto l = testing::run_tool("detect --tag-size 0.8 --tag-size 0.6 " + livox);
  EXPECT_NE(l.out.find("the rings of field 'line' are not level"), std::string::npos) << l.out;
  l = testing::run_tool("detect --json --rings 32 --tag-size 0.8 --tag-size 0.6 " + livox, false);
  ASSERT_EQ(l.exit_code, 0) << l.out;
  EXPECT_EQ(nlohmann::json::parse(l.out.substr(0, l.out.find('\n')))["detections"].size(), 2u)
      << l.out;
}

// `lidartag info` describes any PCD (its header, fields and the scan the detector gets from it,
// or why it gets none) and `lidartag dump` converts it (organised, or into MCAP) as it converts a
// capture's rotations.
TEST_F(VendorPcdsOfTheDemo, LidartagInfoAndDumpTakeAnotherDriversPcd) {
  test::ProcessTempDir dir("vendor_pcds_info");
  const std::string hesai = dir.path() + "/hesai.pcd";
  const size_t written =
      write_vendor_pcd(hesai, layout_named("Hesai"), rotation, velodyne::PcdFormat::kBinary);
  auto r = testing::run_tool("info --json " + hesai, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto info = nlohmann::json::parse(r.out);
  EXPECT_EQ(info["container"], "pcd");
  EXPECT_EQ(info["format"], "binary");
  EXPECT_EQ(info["points"].get<size_t>(), written);
  EXPECT_EQ(info["height"].get<size_t>(), 1u);
  EXPECT_EQ(info["fields"], "x y z intensity timestamp ring");
  EXPECT_TRUE(info["rotation"].empty()) << "no lidartag header comments in another driver's file";
  const auto& scan = info["scan"];
  EXPECT_EQ(scan["rings"].get<int>(), rotation.rings);
  EXPECT_EQ(scan["rings_from"], "field 'ring'");
  // Columns of 0.95 x the cloud's 0.2 degree step: every firing in a column of its own.
  EXPECT_NEAR(scan["column_deg"].get<double>(), 0.19, 1e-4);
  EXPECT_EQ(scan["columns"].get<int>(), 1895);
  // All but a few firings in a column of their own (at 0.2 degrees, about 400 shared one).
  EXPECT_LT(scan["merged"].get<size_t>(), written / 1000);
  EXPECT_EQ(scan["points"].get<size_t>() + scan["merged"].get<size_t>(), written);
  EXPECT_FALSE(scan["organised"].get<bool>());

  // Without a ring field: described, with what would give it rings; --model regresses them.
  Layout no_ring = layout_named("Hesai");
  no_ring.fields.pop_back();
  ASSERT_EQ(no_ring.fields.back().name, "timestamp");
  const std::string bare = dir.path() + "/bare.pcd";
  write_vendor_pcd(bare, no_ring, rotation, velodyne::PcdFormat::kAscii);
  r = testing::run_tool("info " + bare);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("container:      PCD (ascii), unorganised"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("scan:           none: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no ring field"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(--model or --rings N)"), std::string::npos) << r.out;
  r = testing::run_tool("info --json --model vlp32c " + bare, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto regressed = nlohmann::json::parse(r.out)["scan"];
  EXPECT_EQ(regressed["rings"].get<int>(), 32);
  EXPECT_EQ(regressed["rings_from"], "regressed from elevations");
  EXPECT_EQ(regressed["points"].get<size_t>() + regressed["merged"].get<size_t>(), written);

  // dump --organized: the cloud as the detector reads it, rings x columns, its points every one
  // the scan holds; detect on it finds the rotation's tags.
  const std::string out = dir.path() + "/dumped";
  r = testing::run_tool("dump --organized " + hesai + " --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::string dumped = out + "/rotation_000000.pcd";
  EXPECT_NE(
      r.out.find("wrote 1 PCD file (" + std::to_string(scan["points"].get<size_t>()) + " points)"),
      std::string::npos)
      << r.out;
  const velodyne::PcdCloud organised = velodyne::read_pcd(dumped);
  EXPECT_EQ(organised.height, static_cast<size_t>(rotation.rings));
  EXPECT_EQ(organised.width, 1895u);
  Scan back;
  read_pcd_scan(dumped, std::nullopt, 0, 0.2, back);
  expect_sweep_times_and_the_rotations_tags(detector, back, direct);

  // dump --format mcap: one cloud of the scan's points (18 bytes a point, docs/foxglove.md).
  const std::string mcap = dir.path() + "/hesai.mcap";
  r = testing::run_tool("dump " + hesai + " --format mcap --out " + mcap);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote 1 cloud to"), std::string::npos) << r.out;
  auto reader = driver::bag::open_bag(mcap);
  driver::bag::BagMessage m;
  size_t clouds = 0;
  while (reader->next(m)) {
    if (reader->connections()[m.connection].topic != "/lidartag/cloud") continue;
    ++clouds;
    const auto cloud = nlohmann::json::parse(m.data.begin(), m.data.end());
    EXPECT_EQ(cloud["point_stride"].get<size_t>(), 18u);
    // base64: 4 characters per 3 bytes.
    const size_t bytes = cloud["data"].get<std::string>().size() / 4 * 3;
    EXPECT_NEAR(static_cast<double>(bytes), scan["points"].get<double>() * 18, 2.0);
  }
  EXPECT_EQ(clouds, 1u);
  EXPECT_TRUE(reader->error().empty()) << reader->error();
}

// The columns of a cloud of `n` points whose fields hold `values` (one vector per field).
driver::CloudColumns columns_of(const std::vector<driver::CloudSourceField>& fields,
                                const std::vector<std::vector<double>>& values) {
  driver::CloudColumns out;
  driver::cloud_columns_of(
      fields, [&](size_t k, std::vector<double>& column) { column = values[k]; }, out);
  return out;
}

std::vector<double> time_of(const driver::CloudColumns& c) {
  const auto it = std::find(c.names.begin(), c.names.end(), "time");
  return it == c.names.end() ? std::vector<double>{}
                             : c.columns[static_cast<size_t>(it - c.names.begin())];
}

TEST(VendorPcds, EachDriversTimeUnitBecomesSecondsFromTheSweep) {
  const double epoch_s = 1.7e9;
  // Livox's custom point: uint32 ns from the cloud's time base, kept as offsets.
  auto c = columns_of({{"x", false}, {"offset_time", true}}, {{0, 0, 0}, {0, 5e7, 1e8}});
  EXPECT_EQ(time_of(c), (std::vector<double>{0, 0.05, 0.1}));
  EXPECT_EQ(c.source.back(), "offset_time");
  // Ouster's t (uint32 ns from the frame's start): offsets, kept even when the first is not 0.
  c = columns_of({{"t", true}}, {{1e6, 2e6}});
  EXPECT_EQ(time_of(c), (std::vector<double>{1e-3, 2e-3}));
  // Livox's PointCloud2 timestamp: ns since the epoch in a double; seconds from the earliest.
  c = columns_of({{"timestamp", false}}, {{epoch_s * 1e9 + 2e7, epoch_s * 1e9}});
  ASSERT_EQ(time_of(c).size(), 2u);
  EXPECT_NEAR(time_of(c)[0], 0.02, 1e-6);
  EXPECT_EQ(time_of(c)[1], 0.0);
  // Hesai and RoboSense: seconds since the epoch in a double.
  c = columns_of({{"timestamp", false}}, {{epoch_s + 0.1, epoch_s + 0.03}});
  EXPECT_NEAR(time_of(c)[0], 0.07, 1e-6);
  EXPECT_EQ(time_of(c)[1], 0.0);
  // ROS's Velodyne driver: seconds relative to the last packet, negative.
  c = columns_of({{"time", false}}, {{-0.1, -0.04, 0.0}});
  EXPECT_NEAR(time_of(c)[1], 0.06, 1e-12);
  // lidartag's own dump: seconds from the rotation's start, kept as they are.
  c = columns_of({{"time", false}}, {{0.25, 0.001}});
  EXPECT_EQ(time_of(c), (std::vector<double>{0.25, 0.001}));
  // The pair time_sec + time_nsec comes first, from the earliest point.
  c = columns_of({{"time", false}, {"time_sec", true}, {"time_nsec", true}},
                 {{9, 9}, {epoch_s + 1, epoch_s}, {1e8, 9e8}});
  EXPECT_NEAR(time_of(c)[0], 0.2, 1e-9);
  EXPECT_EQ(time_of(c)[1], 0.0);
  EXPECT_EQ(c.source.back(), "time_sec+time_nsec");
  // The first of the ring names present; none of the fields outside the vocabulary.
  c = columns_of({{"line", true}, {"channel", true}, {"reflectivity", false}}, {{1}, {2}, {3}});
  EXPECT_EQ(c.names, (std::vector<std::string>{"ring"}));
  EXPECT_EQ(c.source, (std::vector<std::string>{"channel"}));
}

TEST(VendorPcds, RingsOutOfRangeAreCountedOrAClearError) {
  test::ProcessTempDir dir("vendor_pcds_rings");
  const std::string path = dir.path() + "/rings.pcd";
  const auto write = [&](const std::string& rings) {
    std::ofstream(path, std::ios::trunc)
        << "FIELDS x y z intensity ring\nSIZE 4 4 4 4 4\nTYPE F F F F I\nWIDTH 4\nDATA ascii\n"
        << "5 0 0 100 " << rings.substr(0, rings.find(' ')) << "\n5 1 0 100 1\n"
        << "5 2 0 100 " << rings.substr(rings.find(' ') + 1) << "\n5 3 0 100 -2\n";
  };
  const auto convert = [&](Scan& scan) {
    driver::CloudColumns columns;
    velodyne::pcd_cloud_columns(velodyne::read_pcd_points(path), columns);
    const auto fields = detector::cloud_fields_by_name(columns.names, columns.columns,
                                                       columns.width, columns.height);
    return detector::cloud_to_scan(fields, detector::cloud_scan_options(fields, {}, 0, 0.2), scan);
  };
  write("0 300");  // rings 0 and 1 kept; 300 and -2 are no ring of a LiDAR
  Scan scan;
  const auto report = convert(scan);
  EXPECT_EQ(report.points, 2u);
  EXPECT_EQ(report.skipped_rings, 2u);
  EXPECT_EQ(scan.rings, 2);
  auto r = testing::run_tool("detect " + path);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("2 points with a ring that is not a whole number in 0..1 skipped"),
            std::string::npos)
      << r.out;
  // No point with a ring a LiDAR has: refused, naming the ring field's range.
  std::ofstream(path, std::ios::trunc)
      << "FIELDS x y z intensity line\nSIZE 4 4 4 4 2\nTYPE F F F F U\nWIDTH 2\nDATA ascii\n"
      << "5 0 0 100 4000\n5 1 0 100 300\n";
  EXPECT_THROW(
      {
        try {
          convert(scan);
        } catch (const detector::CloudError& e) {
          EXPECT_NE(std::string(e.what()).find("no point has a ring number in 0..255"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      detector::CloudError);
  r = testing::run_tool("detect " + path);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no point has a ring number"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace lidartag::clouds
