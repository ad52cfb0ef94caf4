// Runs build/bin/lidartag detect on the bundled demo capture (pcap and PCD) and checks what it
// prints against the simulator's truth (pcaps/demo.truth.json).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lidartag/driver/velodyne/io/capture_reader.hpp"
#include "lidartag/driver/velodyne/io/pcd.hpp"
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
    EXPECT_DOUBLE_EQ(d["size_m"].get<double>(), tag["size"].get<double>()) << where;
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

// The summary's deskew line (cmd_detect.cpp's Totals::print_deskew).
std::string fmt_summary(int model, int without, int deskewed, int detections) {
  return "deskew: " + std::to_string(model) + " clusters moved by the tracker's motion model, 0 " +
         "by odometry, " + std::to_string(without) + " fitted as fired (no motion known yet); " +
         std::to_string(deskewed) + " of " + std::to_string(detections) + " detections deskewed";
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
    ASSERT_LT(n, truth["rotations"].size());
    const auto& t = truth["rotations"][n];
    // Rotations by their number, as dump, the daemon, Python and the simulator's truth give it:
    // rotation 0 is the capture's leading partial one, so the first complete one is 1.
    EXPECT_EQ(j["sequence"].get<size_t>(), n + 1);
    EXPECT_EQ(j["sequence"], t["sequence"]);
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

// The size check (issue 33): the demo's 0.8 m tag given as 0.75 m is still found, every rotation
// says what its points measure, the summary says which size to give, and --json carries the
// measure and the warning (its summary line on stderr); the right size warns of nothing.
TEST(CliDetect, ASizeThePointsContradictIsWarnedAboutWithTheSizeToGive) {
  const Result r = run_tool("detect " + kDemo + " --tag-size 0.75", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("SIZE: its points measure 0.8"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("warning: tag16h5 id 0 measures 0.8"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not the 0.750 m given (in 10 of the 10 rotations it was found in)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("give --tag-size 0.80"), std::string::npos) << r.out;
  const auto json = lidartag::testing::run_split(std::string(LIDARTAG_CLI) + " detect " + kDemo +
                                                 " --tag-size 0.75 --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  std::istringstream lines(json.out);
  int warned = 0;
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json rotation = nlohmann::json::parse(line);
    for (const auto& d : rotation["detections"]) {
      EXPECT_NEAR(d["measured_size_m"].get<double>(), 0.8, 0.016) << line;
      warned += d["size_warning"].get<bool>() ? 1 : 0;
    }
  }
  EXPECT_EQ(warned, 10);
  EXPECT_NE(json.err.find("warning: tag16h5 id 0 measures 0.8"), std::string::npos) << json.err;
  const Result right = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6", false);
  EXPECT_EQ(right.out.find("SIZE"), std::string::npos) << right.out;
  EXPECT_EQ(right.out.find("warning"), std::string::npos) << right.out;
}

// A tag too far for the sensor's rings: --clusters names the cluster dropped at clustering and
// what it lacked, in the text and in the JSON.
TEST(CliDetect, ClustersSaysWhatATagTooFarLacked) {
  const auto dir = fs::temp_directory_path() / ("lidartag_far_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  {
    std::ofstream scene(dir / "far.yaml");
    scene << "rotations: 2\nseed: 3\nsensor: {model: vlp16, rpm: 600, height: 1.0}\n"
             "tags:\n  - {family: tag16h5, id: 3, size: 0.8, center: [14.0, 0, 1.0], "
             "rotation: diamond, stand: {width: 0.05}}\n";
  }
  const std::string pcap = (dir / "far.pcap").string();
  ASSERT_EQ(run_tool("sim " + (dir / "far.yaml").string() + " --out " + pcap).exit_code, 0);
  const Result r = run_tool("detect " + pcap + " --tag-size 0.8 --clusters --no-tracker", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("-> clustering/few_features: 2 rings crossed it, 4 features; a cluster "
                       "needs 3 rings and 4 features; the rings are 0.49 m apart at 14.0 m"),
            std::string::npos)
      << r.out;
  const Result j =
      run_tool("detect " + pcap + " --tag-size 0.8 --clusters --no-tracker --json", false);
  ASSERT_EQ(j.exit_code, 0) << j.out;
  std::istringstream lines(j.out);
  int lacked = 0;
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json rotation = nlohmann::json::parse(line);
    for (const auto& c : rotation["cluster_diagnostics"])
      if (c["result"] == "few_features" && c.contains("lacked") &&
          c["lacked"].get<std::string>().find("2 rings crossed it") != std::string::npos)
        ++lacked;
  }
  EXPECT_EQ(lacked, 2);
  fs::remove_all(dir);
}

// The deskew (issue 33): a simulated VLP-16 yawing at 30 deg/s past a 1.2 m tag. With --deskew
// the JSON counts, per rotation, the clusters whose points the tracker's motion model moved (once
// a track knows the motion) and those fitted as fired before that, each detection says what moved
// its points, and the summary (stderr with --json) adds them up; without it every count is 0 and
// every detection "none".
TEST(CliDetect, JsonCountsTheDeskewedClustersOfATurningSensor) {
  TempDir dir;
  {
    std::ofstream scene(dir / "turning.yaml");
    scene << "rotations: 12\nseed: 5\nsensor: {model: vlp16, rpm: 600, height: 1.0, "
             "angular_velocity: [0, 0, 30]}\n"
             "tags:\n  - {family: tag16h5, id: 3, size: 1.2, center: [5.0, 0, 1.0], "
             "rotation: diamond, stand: {width: 0.05}}\n";
  }
  const std::string pcap = (dir / "turning.pcap").string();
  ASSERT_EQ(run_tool("sim " + (dir / "turning.yaml").string() + " --out " + pcap).exit_code, 0);
  struct Counts {
    int rotations = 0, model = 0, ego = 0, without = 0, detections = 0, deskewed = 0;
    bool enabled = false;
  };
  auto count = [](const std::string& out) {
    Counts c;
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);) {
      const nlohmann::json rotation = nlohmann::json::parse(line);
      const nlohmann::json& d = rotation.at("deskew");
      ++c.rotations;
      c.enabled = d.at("enabled").get<bool>();
      c.model += d.at("model").get<int>();
      c.ego += d.at("ego").get<int>();
      c.without += d.at("without_motion").get<int>();
      for (const auto& det : rotation["detections"]) {
        ++c.detections;
        const std::string source = det.at("deskew").get<std::string>();
        EXPECT_TRUE(source == "none" || source == "model") << source;
        c.deskewed += source == "model" ? 1 : 0;
      }
    }
    return c;
  };
  const Result on = lidartag::testing::run_split(std::string(LIDARTAG_CLI) + " detect " + pcap +
                                                 " --tag-size 1.2 --deskew --json");
  ASSERT_EQ(on.exit_code, 0) << on.err;
  const Counts a = count(on.out);
  EXPECT_GE(a.rotations, 10);
  EXPECT_TRUE(a.enabled);
  EXPECT_GT(a.model, 0) << on.out;
  EXPECT_GT(a.without, 0);  // the first rotations, before a track knows the motion
  EXPECT_EQ(a.ego, 0);      // a capture has no odometry
  EXPECT_GT(a.deskewed, 0);
  EXPECT_GE(a.detections, a.rotations - 3);
  EXPECT_NE(on.err.find(fmt_summary(a.model, a.without, a.deskewed, a.detections)),
            std::string::npos)
      << on.err;
  const Result off = run_tool("detect " + pcap + " --tag-size 1.2 --json", false);
  ASSERT_EQ(off.exit_code, 0) << off.out;
  const Counts b = count(off.out);
  EXPECT_EQ(b.rotations, a.rotations);
  EXPECT_FALSE(b.enabled);
  EXPECT_EQ(b.model + b.ego + b.without + b.deskewed, 0);
  EXPECT_GT(b.detections, 0);
  const Result table = run_tool("detect " + pcap + " --tag-size 1.2 --deskew", false);
  EXPECT_NE(table.out.find(fmt_summary(a.model, a.without, a.deskewed, a.detections)),
            std::string::npos)
      << table.out;
  EXPECT_EQ(run_tool("detect " + pcap + " --tag-size 1.2", false).out.find("deskew:"),
            std::string::npos);
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
  EXPECT_EQ(bad.exit_code, 2);  // a configuration error, as lidartagd's
  EXPECT_NE(bad.out.find("detector.features.zeta"), std::string::npos) << bad.out;
}

// The tracker is on by default: every detection gets its track (one per tag, rotations counted,
// confirmed from the 3rd rotation, tracker.min_rotations), its mean pose near the truth;
// --no-tracker and `tracker: {enabled: false}` give the detections alone.
TEST(CliDetect, TracksByDefaultAndNotWithNoTracker) {
  const Result r = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6 --json", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto truth = demo_truth();
  std::istringstream lines(r.out);
  std::string line;
  size_t n = 0;
  while (std::getline(lines, line)) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["tracks"].get<int>(), 2);
    EXPECT_EQ(j["confirmed_tracks"].get<int>(), n >= 2 ? 2 : 0);
    EXPECT_GE(j["timing_ms"]["tracker"].get<double>(), 0.0);
    for (const auto& d : j["detections"]) {
      EXPECT_TRUE(d["decoded"].get<bool>());
      const auto& t = d["track"];
      EXPECT_EQ(t["id"].get<int>(), d["id"].get<int>());  // tags 0 and 1 start tracks 0 and 1
      EXPECT_EQ(t["rotations"].get<size_t>(), n + 1);
      EXPECT_EQ(t["confirmed"].get<bool>(), n >= 2);
      EXPECT_EQ(t["window"].get<size_t>(), n + 1);
      for (const auto& tag : truth["rotations"][n]["tags"])
        if (tag["id"] == d["id"]) {
          EXPECT_LT(dist(t["position"], tag["position"]), 0.02);
          EXPECT_LT(angle_deg(t["orientation"], tag["orientation"]), 2.0);
        }
      EXPECT_LT(t["position_std"][0].get<double>(), 0.01);
      EXPECT_LT(t["angle_std_deg"].get<double>(), 1.0);
    }
    ++n;
  }
  EXPECT_EQ(n, 10u);
  const Result table = run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6", false);
  EXPECT_NE(table.out.find("2 tracks (2 confirmed)"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("track 1: confirmed, 10 rotations"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("tracker"), std::string::npos);

  const Result off =
      run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6 --json --no-tracker", false);
  ASSERT_EQ(off.exit_code, 0) << off.out;
  EXPECT_EQ(off.out.find("\"track\""), std::string::npos);
  EXPECT_EQ(off.out.find("\"tracks\""), std::string::npos);
  EXPECT_EQ(off.out.find("\"decoded\""), std::string::npos);

  TempDir dir;
  {
    std::ofstream c(dir / "off.yaml");
    c << "detector:\n  tag_sizes_m: [0.8, 0.6]\ntracker:\n  enabled: false\n";
    std::ofstream five(dir / "five.yaml");
    five << "detector:\n  tag_sizes_m: [0.8, 0.6]\ntracker:\n  min_rotations: 5\n";
    std::ofstream bad(dir / "bad.yaml");
    bad << "tracker:\n  max_angle_deg: 90\n";
  }
  const Result cfg_off =
      run_tool("detect " + kDemo + " --json --config " + (dir / "off.yaml").string(), false);
  ASSERT_EQ(cfg_off.exit_code, 0) << cfg_off.out;
  EXPECT_EQ(cfg_off.out.find("\"track\""), std::string::npos);
  const Result cfg_five =
      run_tool("detect " + kDemo + " --config " + (dir / "five.yaml").string(), false);
  EXPECT_NE(cfg_five.out.find("track 0: unconfirmed, 4 rotations"), std::string::npos);
  EXPECT_NE(cfg_five.out.find("track 0: confirmed, 5 rotations"), std::string::npos);
  const Result cfg_bad = run_tool("detect " + kDemo + " --config " + (dir / "bad.yaml").string());
  EXPECT_EQ(cfg_bad.exit_code, 2);  // a bad configuration (docs/tools.md)
  EXPECT_NE(cfg_bad.out.find("tracker.max_angle_deg"), std::string::npos) << cfg_bad.out;
}

TEST(CliDetect, PcdWithRingsAndWithout) {
  TempDir dir;
  const Result dump = run_tool("dump " + kDemo + " --out " + (dir / "scans").string());
  ASSERT_EQ(dump.exit_code, 0) << dump.out;
  const std::string with_rings = (dir / "scans" / "rotation_000001.pcd").string();
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
  EXPECT_NE(r.out.find("no ring field: give the sensor model"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(--model or --rings N)"), std::string::npos) << r.out;
}

// The first complete rotation of the demo capture, as `lidartag dump` sees it.
lidartag::Scan first_demo_rotation() {
  lidartag::velodyne::CaptureReader reader(kDemo, {});
  while (const lidartag::Scan* scan = reader.next())
    if (scan->complete) return *scan;
  ADD_FAILURE() << "no complete rotation in " << kDemo;
  return {};
}

TEST(CliDetect, PcdsOfEveryFormatAndLayoutKeepTheStampAndTheTags) {
  TempDir dir;
  const auto truth = demo_truth();
  const std::string sizes = " --tag-size 0.8 --tag-size 0.6 --json";
  // The stamp `detect` reports for the capture's first complete rotation.
  Result r = run_tool("detect " + kDemo + sizes, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const double stamp = nlohmann::json::parse(r.out.substr(0, r.out.find('\n')))["stamp"];
  ASSERT_GT(stamp, 1.6e9);

  std::vector<std::string> files;
  for (const bool organized : {false, true}) {
    const std::string out = (dir / (organized ? "organized" : "flat")).string();
    r = run_tool("dump " + kDemo + " --out " + out + (organized ? " --organized" : ""));
    ASSERT_EQ(r.exit_code, 0) << r.out;
    files.push_back(out + "/rotation_000001.pcd");
  }
  const lidartag::Scan scan = first_demo_rotation();
  const auto organized = lidartag::velodyne::read_pcd(files[1]);
  EXPECT_EQ(organized.height, 32u);  // the VLP-32C's rings
  EXPECT_EQ(organized.width, static_cast<size_t>(scan.columns));
  // The formats `dump` does not write, from the library.
  for (const auto format :
       {lidartag::velodyne::PcdFormat::kAscii, lidartag::velodyne::PcdFormat::kBinaryCompressed}) {
    for (const bool org : {false, true}) {
      files.push_back((dir / (std::string(lidartag::velodyne::pcd_format_name(format)) +
                              (org ? "_organized.pcd" : ".pcd")))
                          .string());
      lidartag::velodyne::write_pcd(files.back(), scan, {format, org});
    }
  }
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    r = run_tool("detect " + file + sizes, false);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["stamp"].get<double>(), stamp);
    // Organised clouds keep every cell; others are binned by azimuth (0.2 degree columns), where
    // a few neighbours of one ring share a column and the nearer is kept.
    const auto points = j["points"].get<size_t>();
    if (file.find("organized") != std::string::npos) {
      EXPECT_EQ(points, scan.point_count());
    } else {
      EXPECT_LE(points, scan.point_count());
      EXPECT_GT(points, scan.point_count() * 98 / 100);
    }
    expect_matches_truth(j["detections"], truth["rotations"][0], file);
  }
}

// A small ascii cloud with rings: 4 rings of 300 points on a cylinder of 5 m, then `extra` lines.
std::string small_cloud(const std::string& extra = "", size_t extra_points = 0) {
  std::ostringstream o;
  o << "VERSION 0.7\nFIELDS x y z intensity ring\nSIZE 4 4 4 4 2\nTYPE F F F F U\n"
    << "COUNT 1 1 1 1 1\nWIDTH " << 1200 + extra_points << "\nHEIGHT 1\nPOINTS "
    << 1200 + extra_points << "\nDATA ascii\n";
  for (int ring = 0; ring < 4; ++ring)
    for (int k = 0; k < 300; ++k) {
      const double a = 2 * M_PI * k / 300;
      o << 5 * std::cos(a) << " " << 5 * std::sin(a) << " " << -0.5 + 0.25 * ring << " 40 " << ring
        << "\n";
    }
  o << extra;
  return o.str();
}

// One "lidartag: error:" line naming the problem, exit code 1.
void expect_one_error(const Result& r, const std::string& words, const std::string& what) {
  EXPECT_EQ(r.exit_code, 1) << what << ": " << r.out;
  EXPECT_EQ(r.out.rfind("lidartag: error: ", 0), 0u) << what << ": " << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << what << ": " << r.out;
  EXPECT_NE(r.out.find(words), std::string::npos) << what << ": " << r.out;
}

TEST(CliDetect, HostilePcdFilesGiveOneErrorLineOrSkipTheBadPoints) {
  TempDir dir;
  const std::string path = (dir / "hostile.pcd").string();
  auto detect = [&](const std::string& text, const std::string& options = "") {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    return run_tool("detect " + path + " " + options);
  };
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n";
  expect_one_error(detect("FIELDS x y z\nSIZE 4 4"), "header ends", "truncated header");
  expect_one_error(detect(xyz + "COUNT 1 1\nWIDTH 1\nDATA ascii\n1 2 3\n"), "COUNT", "counts");
  expect_one_error(detect("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
                   "disagree", "fields");
  expect_one_error(detect(xyz + "WIDTH 5\nDATA binary\n" + std::string(50, '\1')),
                   "binary data holds", "short binary");
  expect_one_error(detect(xyz + "WIDTH 4294967296\nHEIGHT 4294967296\nDATA binary\n"),
                   "out of range", "WIDTH x HEIGHT wrapping to 0");
  expect_one_error(detect(xyz + "WIDTH 1000000000000\nHEIGHT 1\nPOINTS 1000000000000\nDATA "
                                "ascii\n1 2 3\n"),
                   "cannot fit", "absurd POINTS");
  const std::string xyzi = "FIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n";
  expect_one_error(detect(xyzi + "WIDTH 0\nPOINTS 0\nDATA ascii\n", "--rings 16"),
                   "cannot regress rings", "empty cloud");
  // x, y, z alone: tags cannot be decoded without intensity; said, not 0 tags.
  expect_one_error(detect(xyz + "WIDTH 1\nDATA ascii\n1 2 3\n", "--rings 16"), "no intensity field",
                   "xyz only");
  expect_one_error(detect(std::string("\x89PNG\r\n\x1a\n\0\0garbage", 17)), "unknown header line",
                   "not a PCD");

  // Bad points among good ones: skipped with a warning, the rest detected.
  Result r = detect(small_cloud("nan nan nan 0 0\n1e39 0 0 1 1\ninf 1 1 1 1\n", 3));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  // NaN is "no return" (PCL's convention), not a bad point.
  EXPECT_NE(r.out.find("2 points with infinite or out-of-range coordinates skipped"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("0 detections"), std::string::npos) << r.out;
  r =
      detect(small_cloud("5 0 0 1 nan\n5 0 0 1 -1\n5 0 0 1 1e12\n5 0 0 1 2.5\n5 0 0 1 300\n"
                         "5 0 0 1 2000000000\n",
                         6));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("6 points with a ring that is not a whole number in 0..3 skipped"),
            std::string::npos)
      << r.out;
  r = detect(small_cloud("5 0 0 nan 1\n5 0.1 0 -1e300 1\n5 0.2 0 1e300 2\n", 3));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  // Every ring garbage: nothing left to organise.
  r = detect(
      "FIELDS x y z intensity ring\nSIZE 4 4 4 4 4\nTYPE F F F F F\nWIDTH 2\nDATA ascii\n"
      "1 2 3 9 nan\n1 2 3 9 4294967296\n");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no point has a ring number"), std::string::npos) << r.out;
  // Doubles beyond a float in a binary file.
  {
    std::string text =
        "FIELDS x y z intensity ring\nSIZE 8 8 8 4 2\nTYPE F F F F U\nWIDTH 2\nDATA binary\n";
    const float intensity = 40.0f;
    for (double v : {1e300, 2.0, 0.5}) text.append(reinterpret_cast<const char*>(&v), 8);
    text.append(reinterpret_cast<const char*>(&intensity), 4);
    text.append(2, '\0');
    for (double v : {5.0, 0.0, 0.5}) text.append(reinterpret_cast<const char*>(&v), 8);
    text.append(reinterpret_cast<const char*>(&intensity), 4);
    text.append(2, '\0');
    r = detect(text);
    EXPECT_EQ(r.exit_code, 0) << r.out;
    EXPECT_NE(r.out.find("1 points with infinite or out-of-range coordinates skipped"),
              std::string::npos)
        << r.out;
  }
}

TEST(CliDetect, RandomlyDamagedPcdFilesNeverCrashTheTool) {
  TempDir dir;
  const std::string path = (dir / "damaged.pcd").string();
  const std::string base = small_cloud();
  std::mt19937 rng(17);
  for (int k = 0; k < 25; ++k) {
    std::string text = base;
    for (int f = 0; f < 1 + static_cast<int>(rng() % 4); ++f) {
      const size_t at = rng() % std::min<size_t>(text.size(), k % 2 ? text.size() : 200);
      if (rng() % 5 == 0)
        text.resize(at);
      else
        text[at] = static_cast<char>(rng() % 3 == 0 ? rng() : '0' + rng() % 10);
      if (text.empty()) text.assign(1, '\n');  // not = "\n": GCC 12 -O3 false -Wrestrict
    }
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
    const Result r = run_tool("detect " + path);
    ASSERT_TRUE(r.exit_code == 0 || r.exit_code == 1) << "mutant " << k << ": " << r.out;
    if (r.exit_code == 1) {
      EXPECT_NE(r.out.find("lidartag: error: "), std::string::npos) << "mutant " << k << r.out;
    }
  }
}

TEST(CliDetect, TagSizesTakeUnitsAsEveryLengthDoes) {
  // Issue 36: --outer-size 200mm worked, --tag-size 800mm failed with a 300-digit range.
  const Result units = run_tool("detect " + kDemo + " --tag-size 800mm --tag-size 60cm");
  EXPECT_EQ(units.exit_code, 0) << units.out;
  EXPECT_NE(units.out.find("tag16h5 id 0"), std::string::npos) << units.out;
  EXPECT_NE(units.out.find("tag16h5 id 1"), std::string::npos) << units.out;
  const Result bad = run_tool("detect " + kDemo + " --tag-size 0.8parsecs");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.out.find("'0.8parsecs' is not a length"), std::string::npos) << bad.out;
  EXPECT_LT(bad.out.size(), 400u) << bad.out;
}

TEST(CliDetect, BadArgumentsAreUsageErrors) {
  EXPECT_EQ(run_tool("detect " + kDemo + " --tag-size -1").exit_code, 2);
  const Result r = run_tool("detect " + kDemo + " --family tag99h1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("tag99h1"), std::string::npos) << r.out;
}

// Issue 36: the README's detect example, run as printed (from the repository root), finds the
// demo's two tags; with the default size the summary says what the rejected clusters measured.
TEST(CliDetect, TheReadmeExampleWorksAsPrintedAndAWrongSizeSaysWhatItMeasured) {
  std::ifstream readme(LIDARTAG_SOURCE_DIR "/README.md");
  std::string line, example;
  while (std::getline(readme, line)) {
    if (line.rfind("build/bin/lidartag detect ", 0) == 0) {
      example = line.substr(std::string("build/bin/lidartag ").size());
      example = example.substr(0, example.find('#'));
      break;
    }
  }
  ASSERT_FALSE(example.empty()) << "no 'build/bin/lidartag detect' line in README.md";
  const auto r = lidartag::testing::run_command(
      "cd " LIDARTAG_SOURCE_DIR " && " + std::string(LIDARTAG_CLI) + " " + example + " 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(r.out.find("no tags found"), std::string::npos) << example << "\n" << r.out;
  EXPECT_NE(r.out.find("tag16h5 id 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("tag16h5 id 1"), std::string::npos) << r.out;
  const auto wrong = run_tool("detect " + kDemo);
  EXPECT_NE(wrong.out.find("no tags found"), std::string::npos) << wrong.out;
  // The clusters are explained only with --clusters (their diagnostics are always computed, for
  // the summary's last line), and the side given is the outline's (a board's, margin included).
  EXPECT_EQ(wrong.out.find("  cluster "), std::string::npos) << wrong.out;
  const auto explained = run_tool("detect " + kDemo + " --clusters");
  EXPECT_NE(explained.out.find("outline side 0."), std::string::npos) << explained.out;
  EXPECT_NE(explained.out.find("(marker and any board margin)"), std::string::npos);
  // A tag of a family that is not configured is named with the family that fits (issue 36).
  const auto other =
      run_tool("detect " + kDemo + " --tag-size 0.8 --tag-size 0.6 --family tag36h11 --clusters");
  EXPECT_NE(other.out.find("-> decode/other_family (tag16h5 fits better)"), std::string::npos)
      << other.out;
  EXPECT_NE(wrong.out.find("clusters rejected as the wrong size for --tag-size 1.20 m measured 0."),
            std::string::npos)
      << wrong.out;
}

}  // namespace
