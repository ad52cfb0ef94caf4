// Runs build/bin/lidartag detect on the bundled demo capture (pcap and PCD) and checks what it
// prints against the simulator's truth (pcaps/demo.truth.json).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "lidartag/driver/io/pcd.hpp"
#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";
const std::string kDemoTruth = LIDARTAG_SOURCE_DIR "/pcaps/demo.truth.json";

using Result = lidartag::testing::ToolResult;
using lidartag::testing::run_tool;

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("lidartag_detect_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

double dist(const nlohmann::json& a, const nlohmann::json& b) {
  double s = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    const double d = a[k].get<double>() - b[k].get<double>();
    s += d * d;
  }
  return std::sqrt(s);
}

double angle_deg(const nlohmann::json& a, const nlohmann::json& b) {
  double dot = 0;
  for (size_t k = 0; k < 4; ++k) dot += a[k].get<double>() * b[k].get<double>();
  return 2.0 * std::acos(std::min(1.0, std::abs(dot))) * 180.0 / M_PI;
}

// Checks that `detections` hold every truth tag of `truth_rotation` with the right ID and pose.
void expect_matches_truth(const nlohmann::json& detections, const nlohmann::json& truth_rotation,
                          const std::string& where) {
  ASSERT_EQ(detections.size(), truth_rotation["tags"].size()) << where;
  for (const auto& tag : truth_rotation["tags"]) {
    const nlohmann::json* match = nullptr;
    for (const auto& d : detections)
      if (d["id"] == tag["id"] && d["family"] == tag["family"]) match = &d;
    ASSERT_NE(match, nullptr) << where << ": tag " << tag["id"];
    const auto& d = *match;
    EXPECT_DOUBLE_EQ(d["size"].get<double>(), tag["size"].get<double>()) << where;
    EXPECT_LT(dist(d["position"], tag["position"]), 0.02) << where << ": tag " << tag["id"];
    EXPECT_LT(angle_deg(d["orientation"], tag["orientation"]), 2.0) << where;
    ASSERT_EQ(d["corners"].size(), 4u);
    for (size_t k = 0; k < 4; ++k)
      EXPECT_LT(dist(d["corners"][k], tag["corners"][k]), 0.03) << where << ": corner " << k;
    EXPECT_GT(d["score"].get<double>(), 0.8);
    EXPECT_GT(d["margin"].get<double>(), 1.0);
    EXPECT_GT(d["points"].get<int>(), 500);
  }
}

nlohmann::json demo_truth() {
  std::ifstream in(kDemoTruth);
  return nlohmann::json::parse(in);
}

TEST(CliDetect, JsonOfTheDemoCaptureMatchesItsTruth) {
  const Result r = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6 --json", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto truth = demo_truth();
  std::istringstream lines(r.out);
  std::string line;
  size_t n = 0;
  while (std::getline(lines, line)) {
    const auto j = nlohmann::json::parse(line, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << "not one JSON object per line: " << line;
    EXPECT_EQ(j["scan"].get<size_t>(), n);
    ASSERT_LT(n, truth["rotations"].size());
    const auto& t = truth["rotations"][n];
    EXPECT_NEAR(j["stamp"].get<double>(), t["stamp"].get<double>(), 1e-3);
    EXPECT_GT(j["points"].get<int>(), 50000);
    for (const char* stage :
         {"features", "clustering", "validation", "plane", "corners", "pose", "decode"}) {
      EXPECT_TRUE(j["timing_ms"].contains(stage)) << stage;
      EXPECT_GE(j["timing_ms"][stage].get<double>(), 0.0);
    }
    EXPECT_TRUE(j["rejected"].contains("clustering"));
    EXPECT_TRUE(j["rejected"].contains("decode"));
    expect_matches_truth(j["detections"], t, "rotation " + std::to_string(n));
    ++n;
  }
  EXPECT_EQ(n, truth["rotations"].size());
}

TEST(CliDetect, TableSummarisesTheRotations) {
  const Result r = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("10 rotations: tag16h5 id 0 in 10, tag16h5 id 1 in 10 rotations"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("stage"), std::string::npos);
  EXPECT_NE(r.out.find("decode"), std::string::npos);
  // No progress bar when stderr is not a terminal.
  const Result merged = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6");
  EXPECT_EQ(merged.out.find('\r'), std::string::npos);
}

TEST(CliDetect, ConfigFileSetsTheDetector) {
  TempDir dir;
  {
    std::ofstream c(dir / "good.yaml");
    c << "detector:\n  tag_sizes_m: [0.8, 0.6]\n  families: [tag16h5]\n";
    std::ofstream b(dir / "bad.yaml");
    b << "detector:\n  features:\n    zeta: 0.5\n";
  }
  const Result good =
      run_tool("detect " + kDemo + " --config " + (dir / "good.yaml").string(), false);
  ASSERT_EQ(good.exit_code, 0) << good.out;
  EXPECT_NE(good.out.find("tag16h5 id 0 in 10, tag16h5 id 1 in 10"), std::string::npos) << good.out;
  const Result bad = run_tool("detect " + kDemo + " --config " + (dir / "bad.yaml").string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.out.find("detector.features.zeta"), std::string::npos) << bad.out;
}

TEST(CliDetect, PcdWithRingsAndWithout) {
  TempDir dir;
  const Result dump = run_tool("dump " + kDemo + " --out " + (dir / "scans").string());
  ASSERT_EQ(dump.exit_code, 0) << dump.out;
  const std::string with_rings = (dir / "scans" / "scan_000000.pcd").string();
  const auto truth = demo_truth();

  Result r = run_tool("detect " + with_rings + " --tag-size 0.8 --tag-size 0.6 --json", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  expect_matches_truth(j["detections"], truth["rotations"][0], "PCD with rings");

  // The same points without the ring field (ASCII): rings come from the elevations.
  const auto cloud = lidartag::velodyne::read_pcd(with_rings);
  const std::string no_rings = (dir / "no_rings.pcd").string();
  {
    std::ofstream o(no_rings);
    o << "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
      << "WIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << cloud.size()
      << "\nDATA ascii\n";
    const auto &x = cloud.field("x"), &y = cloud.field("y"), &z = cloud.field("z"),
               &i = cloud.field("intensity");
    o.precision(9);
    for (size_t k = 0; k < cloud.size(); ++k)
      o << x[k] << " " << y[k] << " " << z[k] << " " << i[k] << "\n";
  }
  r = run_tool("detect " + no_rings + " --model vlp32c --tag-size 0.8 --tag-size 0.6 --json",
               false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  expect_matches_truth(j["detections"], truth["rotations"][0], "PCD without rings, --model");

  r = run_tool("detect " + no_rings + " --rings 32 --tag-size 0.8 --tag-size 0.6 --json", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  expect_matches_truth(j["detections"], truth["rotations"][0], "PCD without rings, --rings");

  r = run_tool("detect " + no_rings);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no ring field; give --model"), std::string::npos) << r.out;
}

TEST(CliDetect, BadArgumentsAreUsageErrors) {
  EXPECT_EQ(run_tool("detect " + kDemo + " --tag-size -1").exit_code, 2);
  const Result r = run_tool("detect " + kDemo + " --family tag99h1");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("tag99h1"), std::string::npos) << r.out;
}

}  // namespace
