#include "lidartag/driver/velodyne/io/pcd.hpp"

#include <gtest/gtest.h>
#include <lzf.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

namespace lidartag::velodyne {
namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("lidartag_pcd_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

// A small dual-return scan with a known set of valid cells.
Scan make_scan() {
  Scan s;
  s.reserve(4, 2, 10);
  s.columns = 6;
  for (int ret = 0; ret < 2; ++ret)
    for (int ring = 0; ring < 4; ++ring)
      for (int col = 0; col < 6; ++col) {
        const size_t i = s.at(ret, ring, col);
        // Every cell has its firing's azimuth and time, as the decoder gives them.
        s.azimuth_deg[i] = 359.5f - static_cast<float>(col) - 0.01f * static_cast<float>(ring);
        s.time_s[i] = 1e-4f * static_cast<float>(col) + 2e-6f * static_cast<float>(ring);
        if ((ring + col + ret) % 3 == 0) continue;  // no return here
        s.range[i] = 1.0f + static_cast<float>(col);
        s.x[i] = 0.5f * static_cast<float>(col) + static_cast<float>(ret);
        s.y[i] = -0.25f * static_cast<float>(ring);
        s.z[i] = 0.125f * static_cast<float>(ring * col);
        s.intensity[i] = static_cast<uint8_t>(10 * ring + col + 100 * ret);
        s.return_type[i] = ret == 0 ? ReturnType::kLast : ReturnType::kStrongest;
      }
  for (int col = 0; col < 6; ++col) {
    s.column_azimuth_deg[static_cast<size_t>(col)] = 359.25f - static_cast<float>(col);
    s.column_time_s[static_cast<size_t>(col)] = 1e-4 * col - 5e-6;
  }
  s.stamp_ns = 1'700'000'123'456'789'012;
  s.sequence = 42;
  s.model = static_cast<uint8_t>(Model::kVLP32C);
  s.return_mode = 0x39;
  s.complete = true;
  s.rpm = 600.25f;
  return s;
}

constexpr PcdFormat kFormats[] = {PcdFormat::kAscii, PcdFormat::kBinary,
                                  PcdFormat::kBinaryCompressed};

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Little-endian bytes of `v`.
template <typename T>
std::string bytes_of(T v) {
  std::string b(sizeof(T), '\0');
  std::memcpy(b.data(), &v, sizeof(T));
  return b;
}

TEST(Pcd, RoundTripOfEveryFormatKeepsEveryValidCell) {
  for (const PcdFormat format : kFormats) {
    SCOPED_TRACE(std::string(pcd_format_name(format)));
    const Scan scan = make_scan();
    const std::string path = temp_path("scan.pcd");
    const size_t written = write_pcd(path, scan, {format, false});
    EXPECT_EQ(written, scan.point_count());
    const PcdCloud cloud = read_pcd(path);
    EXPECT_EQ(cloud.format, format);
    EXPECT_TRUE(cloud.skipped_fields.empty());
    EXPECT_EQ(cloud.fields, (std::vector<std::string>{"x", "y", "z", "intensity", "ring", "azimuth",
                                                      "time", "return_type"}));
    ASSERT_EQ(cloud.size(), written);
    EXPECT_EQ(cloud.width, written);
    EXPECT_EQ(cloud.height, 1u);
    size_t k = 0;
    for (int ret = 0; ret < scan.returns; ++ret)
      for (int ring = 0; ring < scan.rings; ++ring)
        for (int col = 0; col < scan.columns; ++col) {
          const size_t i = scan.at(ret, ring, col);
          if (!scan.valid(i)) continue;
          SCOPED_TRACE(k);
          EXPECT_EQ(cloud.field("x")[k], scan.x[i]);
          EXPECT_EQ(cloud.field("y")[k], scan.y[i]);
          EXPECT_EQ(cloud.field("z")[k], scan.z[i]);
          EXPECT_EQ(cloud.field("intensity")[k], scan.intensity[i]);
          EXPECT_EQ(cloud.field("ring")[k], ring);
          EXPECT_EQ(cloud.field("azimuth")[k], scan.azimuth_deg[i]);
          EXPECT_EQ(cloud.field("time")[k], scan.time_s[i]);
          EXPECT_EQ(cloud.field("return_type")[k], static_cast<double>(scan.return_type[i]));
          ++k;
        }
    std::filesystem::remove(path);
  }
}

TEST(Pcd, OrganizedRoundTripHasEveryCellAndNaNWithoutAReturn) {
  for (const PcdFormat format : kFormats) {
    SCOPED_TRACE(std::string(pcd_format_name(format)));
    const Scan scan = make_scan();
    const std::string path = temp_path("organized.pcd");
    EXPECT_EQ(write_pcd(path, scan, {format, true}), scan.point_count());
    const PcdCloud cloud = read_pcd(path);
    // PCL's organised layout: WIDTH columns, HEIGHT rows (rings of return 0, then of return 1).
    ASSERT_EQ(cloud.width, static_cast<size_t>(scan.columns));
    ASSERT_EQ(cloud.height, static_cast<size_t>(scan.rings * scan.returns));
    for (int ret = 0; ret < scan.returns; ++ret)
      for (int ring = 0; ring < scan.rings; ++ring)
        for (int col = 0; col < scan.columns; ++col) {
          SCOPED_TRACE(testing::Message() << ret << " " << ring << " " << col);
          const size_t i = scan.at(ret, ring, col);
          const auto k = static_cast<size_t>((ret * scan.rings + ring) * scan.columns + col);
          EXPECT_EQ(cloud.field("ring")[k], ring);
          if (!scan.valid(i)) {
            EXPECT_TRUE(std::isnan(cloud.field("x")[k]));
            EXPECT_TRUE(std::isnan(cloud.field("y")[k]));
            EXPECT_TRUE(std::isnan(cloud.field("z")[k]));
            EXPECT_EQ(cloud.field("intensity")[k], 0.0);
            EXPECT_EQ(cloud.field("return_type")[k], 0.0);
            EXPECT_EQ(cloud.field("azimuth")[k], scan.azimuth_deg[i]);
            EXPECT_EQ(cloud.field("time")[k], scan.time_s[i]);
            continue;
          }
          EXPECT_EQ(cloud.field("x")[k], scan.x[i]);
          EXPECT_EQ(cloud.field("y")[k], scan.y[i]);
          EXPECT_EQ(cloud.field("z")[k], scan.z[i]);
          EXPECT_EQ(cloud.field("intensity")[k], scan.intensity[i]);
          EXPECT_EQ(cloud.field("azimuth")[k], scan.azimuth_deg[i]);
          EXPECT_EQ(cloud.field("time")[k], scan.time_s[i]);
          EXPECT_EQ(cloud.field("return_type")[k], static_cast<double>(scan.return_type[i]));
        }
    std::filesystem::remove(path);
  }
}

TEST(Pcd, HeaderCommentsCarryTheRotationAndViewpointStaysStandard) {
  const Scan scan = make_scan();
  const std::string path = temp_path("stamp.pcd");
  write_pcd(path, scan);
  const std::string text = read_text(path);
  EXPECT_NE(text.find("\n# stamp_ns 1700000123456789012\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nVIEWPOINT 0 0 0 1 0 0 0\n"), std::string::npos) << text;
  const PcdCloud cloud = read_pcd(path);
  ASSERT_TRUE(cloud.rotation.stamp_ns.has_value());
  EXPECT_EQ(*cloud.rotation.stamp_ns, scan.stamp_ns);
  EXPECT_EQ(cloud.rotation.sequence, std::optional<uint64_t>(42));
  EXPECT_EQ(cloud.rotation.model, std::optional<Model>(Model::kVLP32C));
  EXPECT_EQ(cloud.rotation.return_mode, std::optional<uint8_t>(0x39));
  EXPECT_EQ(cloud.rotation.complete, std::optional<bool>(true));
  EXPECT_EQ(cloud.rotation.rpm, std::optional<float>(600.25f));
  Scan back;
  apply_pcd_rotation(cloud.rotation, back);
  EXPECT_EQ(back.stamp_ns, scan.stamp_ns);
  EXPECT_EQ(back.sequence, 42u);
  EXPECT_EQ(back.model, scan.model);
  EXPECT_EQ(back.return_mode, 0x39);
  EXPECT_TRUE(back.complete);
  EXPECT_EQ(back.rpm, 600.25f);
  // A PCD of another tool has none of them: the scan keeps its own.
  std::ofstream(path, std::ios::trunc) << "# .PCD v0.7 - Point Cloud Data file format\n"
                                          "# a comment of another tool\n# sequence of scans 3\n"
                                          "FIELDS x\nSIZE 4\nTYPE F\nWIDTH 1\nDATA ascii\n1\n";
  const PcdCloud other = read_pcd(path);
  EXPECT_FALSE(other.rotation.stamp_ns || other.rotation.sequence || other.rotation.model ||
               other.rotation.return_mode || other.rotation.complete || other.rotation.rpm);
  back.stamp_ns = 7;
  apply_pcd_rotation(other.rotation, back);
  EXPECT_EQ(back.stamp_ns, 7);
  std::filesystem::remove(path);
}

TEST(Pcd, FieldsInAnyOrderOfEveryTypeAndCountAreRead) {
  // Every type a PCD may hold, in an order of its own, with a COUNT 3 field (a normal) and PCL's
  // "_" padding between: the padding and the COUNT > 1 field are skipped, listed as such.
  const std::string header =
      "FIELDS ring _ label x normal big small tiny y z id\n"
      "SIZE 2 1 1 8 4 8 8 1 4 4 4\nTYPE U U I F F U I U F F I\nCOUNT 1 3 1 1 3 1 1 1 1 1 1\n"
      "WIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  std::string binary;
  for (int k = 0; k < 2; ++k) {
    binary += bytes_of<uint16_t>(static_cast<uint16_t>(65535 - k));
    binary += std::string(3, '\x7f');  // padding
    binary += bytes_of<int8_t>(static_cast<int8_t>(-128 + k));
    binary += bytes_of<double>(1.0 / 3.0 + k);
    for (float n : {0.0f, 0.6f, 0.8f}) binary += bytes_of<float>(n);
    binary += bytes_of<uint64_t>((uint64_t{1} << 52) | static_cast<uint64_t>(k));
    binary += bytes_of<int64_t>(-(1ll << 40) - k);
    binary += bytes_of<uint8_t>(static_cast<uint8_t>(255 - k));
    binary += bytes_of<float>(-2.5f * static_cast<float>(k + 1));
    binary += bytes_of<float>(1e-3f);
    binary += bytes_of<int32_t>(-2147483647 - 1 + k);
  }
  const std::string ascii_data =
      "65535 1 2 3 -128 0.33333333333333331 0 0.6 0.8 4503599627370496 -1099511627776 255 -2.5 "
      "0.001 -2147483648\n"
      "65534 1 2 3 -127 1.3333333333333333 0 0.6 0.8 4503599627370497 -1099511627777 254 -5 "
      "0.001 -2147483647\n";
  const std::string path = temp_path("types.pcd");
  for (const bool ascii : {false, true}) {
    SCOPED_TRACE(ascii ? "ascii" : "binary");
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        << header << (ascii ? "DATA ascii\n" + ascii_data : "DATA binary\n" + binary);
    const PcdCloud cloud = read_pcd(path);
    EXPECT_EQ(cloud.fields, (std::vector<std::string>{"ring", "label", "x", "big", "small", "tiny",
                                                      "y", "z", "id"}));
    EXPECT_EQ(cloud.skipped_fields, (std::vector<std::string>{"_", "normal"}));
    ASSERT_EQ(cloud.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      const auto d = static_cast<double>(k);
      EXPECT_EQ(cloud.field("ring")[k], 65535 - d);
      EXPECT_EQ(cloud.field("label")[k], -128 + d);
      EXPECT_EQ(cloud.field("x")[k], 1.0 / 3.0 + d);
      EXPECT_EQ(cloud.field("big")[k], 4503599627370496.0 + d);
      EXPECT_EQ(cloud.field("small")[k], -1099511627776.0 - d);
      EXPECT_EQ(cloud.field("tiny")[k], 255 - d);
      EXPECT_EQ(cloud.field("y")[k], -2.5 * (d + 1));
      EXPECT_EQ(cloud.field("z")[k], static_cast<double>(1e-3f));
      EXPECT_EQ(cloud.field("id")[k], -2147483648.0 + d);
    }
  }
  std::filesystem::remove(path);
}

// PCL's layout of a PointXYZI cloud (x y z, 4 bytes of padding, intensity, 12 bytes of padding)
// written as binary_compressed: each field of every point in turn, LZF-compressed with liblzf
// here in the test, organised 3 x 2.
TEST(Pcd, BinaryCompressedOfPclsLayoutCompressedInTheTestIsRead) {
  const size_t width = 3, height = 2, n = width * height;
  const std::string header =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z _ intensity _\n"
      "SIZE 4 4 4 1 4 1\nTYPE F F F U F U\nCOUNT 1 1 1 4 1 12\nWIDTH 3\nHEIGHT 2\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 6\nDATA binary_compressed\n";
  std::string fields;
  for (size_t i = 0; i < n; ++i) fields += bytes_of<float>(0.5f * static_cast<float>(i));
  for (size_t i = 0; i < n; ++i) fields += bytes_of<float>(i == 4 ? NAN : -1.0f);
  for (size_t i = 0; i < n; ++i) fields += bytes_of<float>(2.0f);
  fields += std::string(4 * n, '\0');
  for (size_t i = 0; i < n; ++i) fields += bytes_of<float>(10.0f * static_cast<float>(i));
  fields += std::string(12 * n, '\0');
  std::string packed(fields.size() * 2 + 16, '\0');
  const unsigned size = lzf_compress(fields.data(), static_cast<unsigned>(fields.size()),
                                     packed.data(), static_cast<unsigned>(packed.size()));
  ASSERT_GT(size, 0u);
  ASSERT_LT(size, fields.size());  // it did compress
  packed.resize(size);
  const std::string path = temp_path("pcl_compressed.pcd");
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      << header << bytes_of<uint32_t>(size)
      << bytes_of<uint32_t>(static_cast<uint32_t>(fields.size())) << packed;
  const PcdCloud cloud = read_pcd(path);
  EXPECT_EQ(cloud.format, PcdFormat::kBinaryCompressed);
  EXPECT_EQ(cloud.fields, (std::vector<std::string>{"x", "y", "z", "intensity"}));
  ASSERT_EQ(cloud.width, width);
  ASSERT_EQ(cloud.height, height);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_EQ(cloud.field("x")[i], 0.5 * static_cast<double>(i));
    EXPECT_EQ(std::isnan(cloud.field("y")[i]), i == 4);
    EXPECT_EQ(cloud.field("z")[i], 2.0);
    EXPECT_EQ(cloud.field("intensity")[i], 10.0 * static_cast<double>(i));
  }
  std::filesystem::remove(path);
}

TEST(Pcd, AnOrganisedCloudOfNoReturnsCompressesFarAndReadsBack) {
  // 32 x 2000 cells without a return: LZF packs the NaNs about 60-fold.
  Scan scan;
  scan.reserve(32, 1, 2000);
  scan.columns = 2000;
  const std::string path = temp_path("empty_organized.pcd");
  write_pcd(path, scan, {PcdFormat::kBinaryCompressed, true});
  const size_t file_size = std::filesystem::file_size(path);
  EXPECT_LT(file_size * 20, 32u * 2000u * 25u);
  const PcdCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 64000u);
  EXPECT_TRUE(std::isnan(cloud.field("x")[63999]));
  EXPECT_EQ(cloud.field("ring")[63999], 31.0);
  std::filesystem::remove(path);
}

// A binary_compressed file made by hand, byte by byte: x = 1, 1, 1 and y = 2, 2, 2 as an LZF
// stream of two literal runs and two back references (so the real decompressor is exercised).
TEST(Pcd, HandMadeBinaryCompressedBytesDecodeToKnownValues) {
  const unsigned char stream[] = {0x03, 0x00, 0x00, 0x80, 0x3f,  // literal run of 4 bytes: 1.0f
                                  0xc0, 0x03,  // back reference: 8 bytes from 4 back (1.0f twice)
                                  0x03, 0x00, 0x00, 0x00, 0x40,  // literal run of 4 bytes: 2.0f
                                  0xc0, 0x03};                   // 2.0f twice
  const std::string path = temp_path("hand.pcd");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << "FIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 3\n"
           "DATA binary_compressed\n"
        << bytes_of<uint32_t>(sizeof(stream)) << bytes_of<uint32_t>(24);
    out.write(reinterpret_cast<const char*>(stream), sizeof(stream));
  }
  const PcdCloud cloud = read_pcd(path);
  EXPECT_EQ(cloud.field("x"), (std::vector<double>{1, 1, 1}));
  EXPECT_EQ(cloud.field("y"), (std::vector<double>{2, 2, 2}));
  std::filesystem::remove(path);
}

TEST(Pcd, APointCloudNeedsXYAndZ) {
  // read_pcd reads any fields; read_pcd_points (lidartag detect, the Python module) refuses a
  // cloud without a coordinate, naming the file and the field.
  const std::string path = temp_path("no_z.pcd");
  std::ofstream(path, std::ios::trunc) << "FIELDS x y intensity\nSIZE 4 4 4\nTYPE F F F\n"
                                          "WIDTH 1\nHEIGHT 1\nDATA ascii\n1 2 3\n";
  EXPECT_EQ(read_pcd(path).size(), 1u);
  try {
    read_pcd_points(path);
    ADD_FAILURE() << "a cloud without z accepted";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("no 'z' field"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  std::ofstream(path, std::ios::trunc) << "FIELDS y z x\nSIZE 4 4 4\nTYPE F F F\n"
                                          "WIDTH 1\nHEIGHT 1\nDATA ascii\n1 2 3\n";
  EXPECT_EQ(read_pcd_points(path).field("x"), (std::vector<double>{3}));
  std::filesystem::remove(path);
}

TEST(Pcd, EmptyScanWritesAValidEmptyCloudInEveryFormat) {
  Scan scan;
  scan.reserve(16, 1, 4);
  const std::string path = temp_path("empty.pcd");
  for (const PcdFormat format : kFormats) {
    SCOPED_TRACE(std::string(pcd_format_name(format)));
    EXPECT_EQ(write_pcd(path, scan, {format, false}), 0u);
    const PcdCloud cloud = read_pcd(path);
    EXPECT_EQ(cloud.size(), 0u);
    EXPECT_TRUE(cloud.has("ring"));
  }
  std::filesystem::remove(path);
}

TEST(Pcd, ReadsAsciiWithOtherTypes) {
  const std::string path = temp_path("ascii.pcd");
  std::ofstream(path) << "# comment\nVERSION .7\nFIELDS x y z label\nSIZE 8 4 4 2\nTYPE F F F I\n"
                         "COUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\n"
                         "DATA ascii\n1.5 2 3 -7\n4 5 6 8\n-1e-3 0 0 32767\n";
  const PcdCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.field("x")[0], 1.5);
  EXPECT_EQ(cloud.field("label")[0], -7);
  EXPECT_EQ(cloud.field("x")[2], -1e-3);
  EXPECT_EQ(cloud.field("label")[2], 32767);
  EXPECT_FALSE(cloud.has("intensity"));
  EXPECT_THROW(cloud.field("intensity"), driver::IoError);
  std::filesystem::remove(path);
}

TEST(Pcd, WidthZeroWithItsPointsCountedIsReadAsOneRow) {
  // A writer that never set WIDTH (Autoware nebula's test clouds: WIDTH 0, HEIGHT 0, POINTS
  // 14673): every point is in the data, so it is read as one row, and said.
  const std::string path = temp_path("width0.pcd");
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 0\n";
  for (const std::string height : {"HEIGHT 0\n", "HEIGHT 1\n", ""}) {
    std::ofstream(path, std::ios::trunc)
        << head << height << "POINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
    const PcdCloud cloud = read_pcd(path);
    EXPECT_TRUE(cloud.width_from_points);
    ASSERT_EQ(cloud.size(), 2u);
    EXPECT_EQ(cloud.width, 2u);
    EXPECT_EQ(cloud.height, 1u);
    EXPECT_EQ(cloud.field("z")[1], 6);
  }
  // An empty cloud stays one, and other disagreements are still refused.
  std::ofstream(path, std::ios::trunc) << head << "HEIGHT 0\nPOINTS 0\nDATA ascii\n";
  EXPECT_EQ(read_pcd(path).size(), 0u);
  EXPECT_FALSE(read_pcd(path).width_from_points);
  std::ofstream(path, std::ios::trunc) << head << "HEIGHT 2\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n";
  EXPECT_THROW(read_pcd(path), driver::IoError);
  // Too few points for what POINTS says: refused as any short file.
  std::ofstream(path, std::ios::trunc) << head << "POINTS 3\nDATA ascii\n1 2 3\n4 5 6\n";
  EXPECT_THROW(read_pcd(path), driver::IoError);
  std::filesystem::remove(path);
}

TEST(Pcd, BadFilesAreIoErrorsNamingTheProblem) {
  const std::string path = temp_path("bad.pcd");
  auto expect_error = [&](const std::string& text, const std::string& words) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    try {
      read_pcd(path);
      ADD_FAILURE() << "expected driver::IoError for: " << words;
    } catch (const driver::IoError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  };
  const std::string header = "FIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 2\nHEIGHT 1\n";
  expect_error(header + "POINTS 2\nDATA binary\n" + std::string(12, '\0'), "binary data holds");
  expect_error(header + "POINTS 2\nDATA ascii\n1 2\n3\n", "ascii data ends");
  expect_error(header + "POINTS 2\nDATA binary_zipped\n", "not supported");
  // binary_compressed: sizes missing, wrong, beyond the file; a corrupt LZF stream.
  const std::string compressed = header + "POINTS 2\nDATA binary_compressed\n";
  expect_error(compressed + "\x05\0\0", "ends before its sizes");
  expect_error(compressed + bytes_of<uint32_t>(2) + bytes_of<uint32_t>(20) + "ab",
               "unpacks to 20 bytes, but 2 points of 8 bytes need 16");
  expect_error(compressed + bytes_of<uint32_t>(100) + bytes_of<uint32_t>(16) + "ab",
               "holds 2 of 100 compressed bytes");
  // A back reference before the start of the output: LZF refuses it.
  expect_error(compressed + bytes_of<uint32_t>(2) + bytes_of<uint32_t>(16) + "\xe0\x10", "corrupt");
  // Literal runs that stop short of the size the header promises.
  expect_error(compressed + bytes_of<uint32_t>(3) + bytes_of<uint32_t>(16) +
                   "\x01"
                   "ab",
               "corrupt");
  expect_error("FIELDS x x\nSIZE 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n", "appears twice");
  expect_error("FIELDS x\nSIZE 4\nTYPE F\nCOUNT 0\nWIDTH 1\nDATA ascii\n1\n", "COUNT 0");
  expect_error("FIELDS x\nSIZE 2\nTYPE F\nWIDTH 1\nDATA ascii\n1\n", "unsupported type F2");
  expect_error("# stamp_ns 12x\nFIELDS x\nSIZE 4\nTYPE F\nWIDTH 1\nDATA ascii\n1\n",
               "header comment 'stamp_ns': '12x'");
  expect_error("# model vlp64\nFIELDS x\nSIZE 4\nTYPE F\nWIDTH 1\nDATA ascii\n1\n",
               "header comment 'model'");
  expect_error("# complete yes\nFIELDS x\nSIZE 4\nTYPE F\nWIDTH 1\nDATA ascii\n1\n",
               "'yes' is not 0 or 1");
  expect_error("FIELDS x y\nSIZE 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n", "disagree");
  expect_error("FIELDS x\nSIZE 3\nTYPE F\nWIDTH 1\nDATA ascii\n1\n", "unsupported type");
  expect_error("FIELDS x\nSIZE 4\nTYPE F\nCOUNT 3\nWIDTH 1\nDATA ascii\n1 2\n", "ascii data ends");
  expect_error("FIELDS x\nSIZE 4\nTYPE F\nWIDTH 1000000000000\nDATA binary\n", "cannot fit");
  expect_error(header + "POINTS 2\n", "header ends");
  // A header lying about its points; a type PCD does not have.
  expect_error(header + "POINTS 3\nDATA binary\n" + std::string(24, '\0'),
               "POINTS is not WIDTH x HEIGHT");
  expect_error("FIELDS x\nSIZE 4\nTYPE X\nWIDTH 1\nDATA ascii\n1\n", "unsupported type X4");
  EXPECT_THROW(read_pcd("/nonexistent-lidartag/x.pcd"), driver::IoError);
  std::filesystem::remove(path);
}

TEST(Pcd, AbsurdSizesAreIoErrorsNotWrapsOrHugeAllocations) {
  const std::string path = temp_path("absurd.pcd");
  auto expect_error = [&](const std::string& text, const std::string& words) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    try {
      const PcdCloud cloud = read_pcd(path);
      ADD_FAILURE() << "accepted " << cloud.size() << " points for: " << words;
    } catch (const driver::IoError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  const std::string fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n";
  const std::string data = "DATA binary\n" + std::string(24, '\0');
  // 2^32 x 2^32 wraps to 0 points: an empty cloud from a file that claims 2^64.
  expect_error(fields + "WIDTH 4294967296\nHEIGHT 4294967296\n" + data, "out of range");
  expect_error(fields + "WIDTH 4294967296\nHEIGHT 4294967296\nPOINTS 0\n" + data, "out of range");
  expect_error(fields + "WIDTH 9223372036854775809\nHEIGHT 2\nPOINTS 2\n" + data, "out of range");
  expect_error(fields + "WIDTH 18446744073709551615\nHEIGHT 1\n" + data, "cannot fit");
  expect_error(fields + "WIDTH -2\nHEIGHT 1\n" + data, "PCD file");
  expect_error(fields + "WIDTH 2\nHEIGHT 1\nPOINTS 3\n" + data, "POINTS is not WIDTH x HEIGHT");
  expect_error(fields + "WIDTH 3\nHEIGHT 1\n" + data, "binary data holds");
  expect_error(fields + "WIDTH 99999\nHEIGHT 99999\nDATA ascii\n1 2 3\n", "cannot fit");
  expect_error("FIELDS x y z\nSIZE 4 4\n", "header ends");
  expect_error("FIELDS\nSIZE\nTYPE\nWIDTH 1\nDATA ascii\n", "no FIELDS");
  expect_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2 3\n", "disagree");
  expect_error("FIELDS x\nSIZE 18446744073709551615\nTYPE F\nWIDTH 1\nDATA binary\n", "type");
  expect_error(fields + "WIDTH 1\nDATA ascii\n1 x 3\n", "'x'");
  expect_error(fields + "WIDTH 1\nDATA ascii\n1 2 1e999\n", "not a number");
  // 200,000 fields (2.9 MB of header) once took 28 s to refuse (a quadratic duplicate check):
  // refused by count; 4,000 distinct fields with one repeated at the end, in linear time.
  auto header_of = [](size_t n, bool repeat_last) {
    std::string names = "FIELDS", sizes = "SIZE", types = "TYPE";
    for (size_t i = 0; i < n; ++i) {
      names += " f" + std::to_string(repeat_last && i + 1 == n ? 0 : i);
      sizes += " 4";
      types += " F";
    }
    return names + "\n" + sizes + "\n" + types + "\nWIDTH 1\nDATA binary\n" +
           std::string(4 * n, '\0');
  };
  expect_error(header_of(200000, false), "200000 FIELDS, more than the limit of 4096");
  expect_error(header_of(4000, true), "field 'f0' appears twice");
  std::filesystem::remove(path);
}

TEST(Pcd, AsciiNanAndInfAsPclWritesThemAreRead) {
  // PCL writes "nan" for the invalid points of organised clouds; they are values, not the end.
  const std::string path = temp_path("nan.pcd");
  std::ofstream(path) << "FIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 4\nHEIGHT "
                         "1\nDATA ascii\n1 2 3 4\nnan nan nan 0\n-inf inf +5 NaN\n5 6 7 8\n";
  const PcdCloud cloud = read_pcd(path);
  ASSERT_EQ(cloud.size(), 4u);
  EXPECT_EQ(cloud.field("x")[0], 1.0);
  EXPECT_TRUE(std::isnan(cloud.field("x")[1]));
  EXPECT_TRUE(std::isinf(cloud.field("x")[2]) && cloud.field("x")[2] < 0);
  EXPECT_EQ(cloud.field("z")[2], 5.0);
  EXPECT_TRUE(std::isnan(cloud.field("intensity")[2]));
  EXPECT_EQ(cloud.field("intensity")[3], 8.0);
  std::filesystem::remove(path);
}

TEST(Pcd, RandomlyDamagedFilesAreReadConsistentlyOrRefused) {
  const std::string good = temp_path("good.pcd");
  write_pcd(good, make_scan());
  const std::string binary = read_text(good);
  write_pcd(good, make_scan(), {PcdFormat::kBinaryCompressed, true});
  const std::string compressed = read_text(good);
  std::ostringstream ascii;
  ascii << "VERSION 0.7\nFIELDS x y z intensity ring\nSIZE 4 4 4 4 2\nTYPE F F F F U\n"
           "COUNT 1 1 1 1 1\nWIDTH 6\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 6\nDATA ascii\n";
  for (int k = 0; k < 6; ++k) ascii << k << ".5 -" << k << " 0.25 " << 10 * k << " " << k << "\n";
  const std::string path = temp_path("damaged.pcd");
  std::mt19937 rng(3);
  int read = 0, refused = 0;
  for (int k = 0; k < 600; ++k) {
    std::string text = k % 3 == 0 ? binary : k % 3 == 1 ? compressed : ascii.str();
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      const size_t at = rng() % text.size();
      switch (rng() % 4) {
        case 0:  // a random byte
          text[at] = static_cast<char>(rng());
          break;
        case 1:  // a digit, so that numbers in the header change
          text[at] = static_cast<char>('0' + rng() % 10);
          break;
        case 2:  // cut
          text.resize(at);
          break;
        default:  // a line dropped or doubled
          if (const size_t nl = text.find('\n', at); nl != std::string::npos) {
            const size_t start = text.rfind('\n', at);
            const size_t from = start == std::string::npos ? 0 : start + 1;
            if (rng() % 2)
              text.erase(from, nl + 1 - from);
            else
              text.insert(from, text.substr(from, nl + 1 - from));
          }
      }
      if (text.empty()) text = "x";
    }
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    try {
      const PcdCloud cloud = read_pcd(path);
      ++read;
      ASSERT_EQ(cloud.columns.size(), cloud.fields.size());
      for (const auto& column : cloud.columns) ASSERT_EQ(column.size(), cloud.size());
      ASSERT_LE(cloud.size() * cloud.fields.size(), text.size());
    } catch (const driver::IoError& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  EXPECT_GT(read, 0);
  EXPECT_GT(refused, 0);
  std::filesystem::remove(path);
  std::filesystem::remove(good);
}

TEST(Pcd, ReadsTheReferenceScanOfAnotherDecoder) {
  const std::string path = LIDARTAG_SHARED_DIR "/captures/reference/vlp16_dual_nebula_scan.pcd";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "reference not available: " << path;
  const PcdCloud cloud = read_pcd(path);
  EXPECT_EQ(cloud.size(), 14831u);  // the README's figure
  const auto& channel = cloud.field("channel");
  EXPECT_GE(*std::min_element(channel.begin(), channel.end()), 0);
  EXPECT_LE(*std::max_element(channel.begin(), channel.end()), 15);
}

}  // namespace
}  // namespace lidartag::velodyne
