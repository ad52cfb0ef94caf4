#include "lidartag/driver/io/pcd.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
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
        if ((ring + col + ret) % 3 == 0) continue;  // no return here
        const size_t i = s.at(ret, ring, col);
        s.range[i] = 1.0f + static_cast<float>(col);
        s.x[i] = 0.5f * static_cast<float>(col) + static_cast<float>(ret);
        s.y[i] = -0.25f * static_cast<float>(ring);
        s.z[i] = 0.125f * static_cast<float>(ring * col);
        s.intensity[i] = static_cast<uint8_t>(10 * ring + col + 100 * ret);
        s.azimuth_deg[i] = 359.5f - static_cast<float>(col);
        s.time_s[i] = 1e-4f * static_cast<float>(col);
        s.return_type[i] = ret == 0 ? ReturnType::kLast : ReturnType::kStrongest;
      }
  return s;
}

TEST(Pcd, BinaryRoundTripKeepsEveryValidCell) {
  const Scan scan = make_scan();
  const std::string path = temp_path("scan.pcd");
  const size_t written = write_pcd(path, scan);
  EXPECT_EQ(written, scan.point_count());
  const PcdCloud cloud = read_pcd(path);
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
  // Exact file size: header plus 25 bytes per point.
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  EXPECT_GT(static_cast<size_t>(in.tellg()), 25 * written);
  std::filesystem::remove(path);
}

TEST(Pcd, EmptyScanWritesAValidEmptyCloud) {
  Scan scan;
  scan.reserve(16, 1, 4);
  const std::string path = temp_path("empty.pcd");
  EXPECT_EQ(write_pcd(path, scan), 0u);
  const PcdCloud cloud = read_pcd(path);
  EXPECT_EQ(cloud.size(), 0u);
  EXPECT_TRUE(cloud.has("ring"));
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
  EXPECT_THROW(cloud.field("intensity"), IoError);
  std::filesystem::remove(path);
}

TEST(Pcd, BadFilesAreIoErrorsNamingTheProblem) {
  const std::string path = temp_path("bad.pcd");
  auto expect_error = [&](const std::string& text, const std::string& words) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    try {
      read_pcd(path);
      ADD_FAILURE() << "expected IoError for: " << words;
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  };
  const std::string header = "FIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 2\nHEIGHT 1\n";
  expect_error(header + "POINTS 2\nDATA binary\n" + std::string(12, '\0'), "binary data holds");
  expect_error(header + "POINTS 2\nDATA ascii\n1 2\n3\n", "ascii data ends");
  expect_error(header + "POINTS 2\nDATA binary_compressed\n", "not supported");
  expect_error("FIELDS x y\nSIZE 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n", "disagree");
  expect_error("FIELDS x\nSIZE 3\nTYPE F\nWIDTH 1\nDATA ascii\n1\n", "unsupported type");
  expect_error("FIELDS x\nSIZE 4\nTYPE F\nCOUNT 3\nWIDTH 1\nDATA ascii\n1 2 3\n", "COUNT");
  expect_error("FIELDS x\nSIZE 4\nTYPE F\nWIDTH 1000000000000\nDATA binary\n", "cannot fit");
  expect_error(header + "POINTS 2\n", "header ends");
  EXPECT_THROW(read_pcd("/nonexistent-lidartag/x.pcd"), IoError);
  std::filesystem::remove(path);
}

TEST(Pcd, AbsurdSizesAreIoErrorsNotWrapsOrHugeAllocations) {
  const std::string path = temp_path("absurd.pcd");
  auto expect_error = [&](const std::string& text, const std::string& words) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    try {
      const PcdCloud cloud = read_pcd(path);
      ADD_FAILURE() << "accepted " << cloud.size() << " points for: " << words;
    } catch (const IoError& e) {
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
  std::ifstream in(good, std::ios::binary);
  std::ostringstream file;
  file << in.rdbuf();
  const std::string binary = file.str();
  std::ostringstream ascii;
  ascii << "VERSION 0.7\nFIELDS x y z intensity ring\nSIZE 4 4 4 4 2\nTYPE F F F F U\n"
           "COUNT 1 1 1 1 1\nWIDTH 6\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 6\nDATA ascii\n";
  for (int k = 0; k < 6; ++k) ascii << k << ".5 -" << k << " 0.25 " << 10 * k << " " << k << "\n";
  const std::string path = temp_path("damaged.pcd");
  std::mt19937 rng(3);
  int read = 0, refused = 0;
  for (int k = 0; k < 400; ++k) {
    std::string text = k % 2 ? binary : ascii.str();
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
    } catch (const IoError& e) {
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
