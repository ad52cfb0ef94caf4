// `lidartag info/dump/detect/render` on the real Ouster captures (../shared/captures/ouster;
// skipped when absent), run as a user would: metadata from --metadata or NAME.json beside
// NAME.pcap.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
using lidartag::testing::run_tool;

const std::string kDir = std::string(LIDARTAG_SHARED_DIR) + "/captures/ouster/pcaps/";

struct Expected {
  const char* pcap;
  const char* metadata;  // nullptr: NAME.json beside
  const char* profile;
  unsigned lidar, imu, frames, most_columns;
  unsigned whole;  // frames with every packet: all but the FUSA capture's part of one
};

// The captures' README: packets, frames; the IMU packets as in the files.
constexpr Expected kCaptures[] = {
    {"OS-1-32-G_v2.1.1_1024x10", nullptr, "LEGACY", 64, 0, 1, 1024, 1},
    {"OS-2-32-U0_v2.0.0_1024x10", nullptr, "LEGACY", 64, 0, 1, 1024, 1},
    {"OS-0-32-U1_v2.2.0_1024x10", nullptr, "RNG19_RFL8_SIG16_NIR16_DUAL", 64, 10, 1, 1024, 1},
    {"OS-0-128-U1_v2.3.0_1024x10", nullptr, "RNG15_RFL8_NIR8", 64, 10, 1, 1024, 1},
    {"OS-2-128-U1_v2.3.0_1024x10", nullptr, "RNG19_RFL8_SIG16_NIR16", 64, 10, 1, 1024, 1},
    {"OS-1-128_v2.3.0_1024x10_lb_n3", "OS-1-128_v2.3.0_1024x10", "RNG15_RFL8_NIR8", 192, 30, 3,
     1024, 3},
    {"OS-1-128_767798045_1024x10_20230712_120049", nullptr, "FUSA_RNG15_RFL8_NIR8_DUAL", 8, 2, 1,
     128, 0},
};

TEST(CliOuster, InfoReportsEveryCapturesPacketsAndFrames) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  for (const Expected& e : kCaptures) {
    SCOPED_TRACE(e.pcap);
    std::string args = "info --json '" + kDir + e.pcap + ".pcap'";
    if (e.metadata) args += " --metadata '" + kDir + e.metadata + ".json'";
    const auto r = run_tool(args, false);
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["vendor"], "ouster");
    EXPECT_EQ(j["profile"], e.profile);
    EXPECT_EQ(j["packets"]["lidar"], e.lidar);
    EXPECT_EQ(j["packets"]["imu"], e.imu);
    EXPECT_EQ(j["packets"]["other"], 0);
    EXPECT_EQ(j["frames"]["total"], e.frames);
    EXPECT_EQ(j["frames"]["most_columns"], e.most_columns);
    EXPECT_GT(j["frames"]["points"].get<int>(), 10000);
    for (const auto& [status, count] : j["refused"].items()) EXPECT_EQ(count, 0) << status;
    EXPECT_EQ(j["missing_packets"], 0);
  }
  // Text output names the sensor.
  const auto text = run_tool("info '" + kDir + "OS-2-128-U1_v2.3.0_1024x10.pcap'");
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.out.find("Ouster OS-2-128"), std::string::npos) << text.out;
}

TEST(CliOuster, MalformedMetadataIsRefusedNamingTheKey) {
  const std::string bad = std::string(LIDARTAG_SHARED_DIR) +
                          "/captures/ouster/metadata/malformed/" +
                          "incomplete_data_format_legacy.json";
  if (!fs::exists(bad)) GTEST_SKIP() << "Ouster captures not found at " << bad;
  const auto r =
      run_tool("info '" + kDir + "OS-1-32-G_v2.1.1_1024x10.pcap' --metadata '" + bad + "'");
  EXPECT_EQ(r.exit_code, 2);  // a file the user must change (exit_codes.hpp)
  EXPECT_NE(r.out.find("data_format.columns_per_frame"), std::string::npos) << r.out;
  for (const char* command : {"detect", "dump --out /nonexistent-never-created", "render"}) {
    SCOPED_TRACE(command);
    const auto c = run_tool(std::string(command) + " '" + kDir +
                            "OS-1-32-G_v2.1.1_1024x10.pcap' --metadata '" + bad + "'");
    EXPECT_EQ(c.exit_code, 2) << c.out;
    EXPECT_NE(c.out.find("data_format.columns_per_frame"), std::string::npos) << c.out;
  }
}

// The capture's own arguments: the pcap and, where it is not NAME.json beside it, --metadata.
std::string capture_args(const Expected& e) {
  std::string args = " '" + kDir + e.pcap + ".pcap'";
  if (e.metadata) args += " --metadata '" + kDir + e.metadata + ".json'";
  return args;
}

// The per-frame JSON lines of `detect --json` (stdout alone).
std::vector<nlohmann::json> json_lines(const std::string& out) {
  std::vector<nlohmann::json> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line.front() == '{') lines.push_back(nlohmann::json::parse(line));
  return lines;
}

TEST(CliOuster, DetectFindsNoTagInAnyCaptureAndCountsItsWholeFrames) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  for (const Expected& e : kCaptures) {
    SCOPED_TRACE(e.pcap);
    const auto r = run_tool("detect --json --no-tracker" + capture_args(e), false);
    if (e.whole == 0) {  // only a partial frame: refused without --partial, naming it
      EXPECT_EQ(r.exit_code, 1);
      const auto text = run_tool("detect" + capture_args(e));
      EXPECT_NE(text.out.find("no whole frame, only 1 partial one"), std::string::npos) << text.out;
    } else {
      ASSERT_EQ(r.exit_code, 0) << r.out;
    }
    const auto lines = json_lines(r.out);
    EXPECT_EQ(lines.size(), e.whole);
    for (const auto& j : lines) {
      EXPECT_TRUE(j["detections"].empty()) << j.dump();
      EXPECT_GT(j["points"].get<int>(), 10000);
      EXPECT_GT(j["features"].get<int>(), 300);
    }
    // --partial adds the FUSA capture's part of a frame: every frame of every capture.
    const auto all = run_tool("detect --json --no-tracker --partial" + capture_args(e), false);
    ASSERT_EQ(all.exit_code, 0) << all.out;
    const auto every = json_lines(all.out);
    EXPECT_EQ(every.size(), e.frames);
    for (const auto& j : every) EXPECT_TRUE(j["detections"].empty()) << j.dump();
  }
}

// A temporary folder, removed with its files.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("lidartag-ouster-" + name + "-" + std::to_string(::getpid()))) {
    fs::remove_all(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

// A PCD header's value of `key` (e.g. "POINTS").
long pcd_header(const fs::path& file, const std::string& key) {
  std::ifstream in(file, std::ios::binary);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(key + " ", 0) == 0) return std::stol(line.substr(key.size() + 1));
    if (line.rfind("DATA", 0) == 0) break;
  }
  return -1;
}

TEST(CliOuster, DumpWritesOnePcdPerWholeFrameWithEveryPoint) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  for (const Expected& e : kCaptures) {
    if (e.whole == 0) continue;
    SCOPED_TRACE(e.pcap);
    // info counts the points of every frame through its own loop: here every frame is whole.
    const auto info = run_tool("info --json" + capture_args(e), false);
    ASSERT_EQ(info.exit_code, 0) << info.out;
    const long points = nlohmann::json::parse(info.out)["frames"]["points"].get<long>();
    TempDir dir("dump");
    const auto r = run_tool("dump" + capture_args(e) + " --out '" + dir.path.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    size_t files = 0;
    long dumped = 0;
    for (const auto& f : fs::directory_iterator(dir.path)) {
      ++files;
      dumped += pcd_header(f.path(), "POINTS");
    }
    EXPECT_EQ(files, e.whole);
    EXPECT_EQ(dumped, points);
    EXPECT_NE(r.out.find(std::to_string(points) + " points)"), std::string::npos) << r.out;
  }
  // Organised: the destaggered image, columns x rings (x returns).
  const Expected& e = kCaptures[3];  // OS-0-128, one return
  TempDir dir("organized");
  const auto r =
      run_tool("dump --organized" + capture_args(e) + " --out '" + dir.path.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const fs::path file = dir.path / "rotation_000000.pcd";
  EXPECT_EQ(pcd_header(file, "WIDTH"), 1024);
  EXPECT_EQ(pcd_header(file, "HEIGHT"), 128);
}

TEST(CliOuster, RenderWritesAPng) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  TempDir dir("render");
  fs::create_directories(dir.path);
  const auto r =
      run_tool("render" + capture_args(kCaptures[0]) + " -o '" + dir.path.string() + "/'");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const fs::path png = dir.path / (std::string(kCaptures[0].pcap) + "-rotation0.png");
  ASSERT_TRUE(fs::exists(png)) << r.out;
  std::ifstream in(png, std::ios::binary);
  char signature[8] = {};
  in.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  EXPECT_GT(fs::file_size(png), 10000u);
  EXPECT_NE(r.out.find("bird's-eye view"), std::string::npos) << r.out;
}

TEST(CliOuster, MetadataOfAnotherSensorIsRefusedWithExitTwo) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  struct Case {
    const char* pcap;
    const char* metadata;
    const char* says;
  };
  const Case cases[] = {
      // Another profile and pixel count: the packets' size names what they are.
      {"OS-1-32-G_v2.1.1_1024x10", "OS-2-128-U1_v2.3.0_1024x10",
       "(the first is 6464 bytes: LEGACY with 32 pixels and 16 columns per packet)"},
      // The same profile and size, another sensor: its identity.
      {"OS-0-128-U1_v2.3.0_1024x10", "OS-1-128_v2.3.0_1024x10", "lidar packets carry init id"},
  };
  for (const Case& c : cases) {
    for (const char* command : {"detect", "dump --out /nonexistent-never-created", "render"}) {
      SCOPED_TRACE(std::string(c.pcap) + " " + command);
      const auto r = run_tool(std::string(command) + " '" + kDir + c.pcap + ".pcap' --metadata '" +
                              kDir + c.metadata + ".json'");
      EXPECT_EQ(r.exit_code, 2) << r.out;
      EXPECT_NE(r.out.find("the metadata does not describe this capture's sensor"),
                std::string::npos)
          << r.out;
      EXPECT_NE(r.out.find(c.says), std::string::npos) << r.out;
    }
  }
}

TEST(CliOuster, VelodyneOptionsAreRefusedForAnOusterCapture) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  for (const char* option : {"--model vlp16", "--cut 90"}) {
    SCOPED_TRACE(option);
    std::string args = "detect ";
    args += option;
    args += capture_args(kCaptures[0]);
    const auto r = run_tool(args);
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("is for Velodyne captures"), std::string::npos) << r.out;
  }
}

TEST(CliOuster, SignalIntensityWhereTheProfileHasIt) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  // RNG19: SIGNAL, clamped to 255.
  const auto ok = run_tool("detect --json --intensity signal" + capture_args(kCaptures[4]), false);
  ASSERT_EQ(ok.exit_code, 0) << ok.out;
  EXPECT_EQ(json_lines(ok.out).size(), 1u);
  // The same points with other intensities: the dumps differ, their point counts do not.
  std::string bytes[2];
  long points[2] = {0, 0};
  const char* sources[2] = {"reflectivity", "signal"};
  for (int k = 0; k < 2; ++k) {
    TempDir dir(sources[k]);
    const auto r = run_tool(std::string("dump --intensity ") + sources[k] +
                            capture_args(kCaptures[4]) + " --out '" + dir.path.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const fs::path file = dir.path / "rotation_000000.pcd";
    points[k] = pcd_header(file, "POINTS");
    std::ifstream in(file, std::ios::binary);
    std::stringstream content;
    content << in.rdbuf();
    bytes[k] = content.str();
  }
  EXPECT_EQ(points[0], points[1]);
  EXPECT_GT(points[0], 10000);
  EXPECT_EQ(bytes[0].size(), bytes[1].size());
  EXPECT_NE(bytes[0], bytes[1]);
  // RNG15 has no SIGNAL: a usage error naming it.
  const auto no = run_tool("detect --intensity signal" + capture_args(kCaptures[3]));
  EXPECT_EQ(no.exit_code, 2) << no.out;
  EXPECT_NE(no.out.find("has no SIGNAL field"), std::string::npos) << no.out;
}

TEST(CliOuster, AnotherJsonBesideAVelodyneCaptureIsNotTakenForMetadata) {
  const fs::path velodyne = std::string(LIDARTAG_SHARED_DIR) + "/captures/vlp16_rlu.pcap";
  if (!fs::exists(velodyne)) GTEST_SKIP() << "captures not found at " << velodyne;
  const fs::path dir =
      fs::temp_directory_path() / ("lidartag-ouster-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::create_symlink(velodyne, dir / "scan.pcap");
  std::ofstream(dir / "scan.json") << R"({"tags": [], "truth": "a simulator's"})";
  const auto r = run_tool("info --json '" + (dir / "scan.pcap").string() + "'", false);
  fs::remove_all(dir);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["model"], "vlp16");
  EXPECT_FALSE(j.contains("vendor"));
}

}  // namespace
