// `lidartag info/dump/detect/render` on the real Ouster captures (../shared/captures/ouster;
// skipped when absent), run as a user would: metadata from --metadata or NAME.json beside
// NAME.pcap.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "lidartag/driver/velodyne/io/pcd.hpp"
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

// --model takes Ouster names too (any case): the metadata must describe that sensor.
TEST(CliOuster, ModelNamesTheOusterSensorTheMetadataMustDescribe) {
  if (!fs::exists(kDir)) GTEST_SKIP() << "Ouster captures not found at " << kDir;
  // Each capture's model as its product line names it, in capitals, and one it is not.
  const char* models[][2] = {{"OS1-32", "os1-64"},   {"OS2-32", "os0-32"},  {"OS0-32", "os2-32"},
                             {"OS0-128", "os1-128"}, {"OS2-128", "os2-64"}, {"os1-128", "os1-64"},
                             {"OS1-128", "os0-128"}};
  static_assert(std::size(models) == std::size(kCaptures));
  for (size_t i = 0; i < std::size(kCaptures); ++i) {
    SCOPED_TRACE(kCaptures[i].pcap);
    const auto right = run_tool(
        std::string("info --json --model ") + models[i][0] + capture_args(kCaptures[i]), false);
    ASSERT_EQ(right.exit_code, 0) << right.out;
    EXPECT_EQ(nlohmann::json::parse(right.out)["frames"]["total"], kCaptures[i].frames);
    for (const char* command : {"info", "detect"}) {
      const auto wrong =
          run_tool(std::string(command) + " --model " + models[i][1] + capture_args(kCaptures[i]));
      EXPECT_EQ(wrong.exit_code, 2) << wrong.out;
      EXPECT_NE(
          wrong.out.find(std::string("model ") + models[i][1] + " is configured but the metadata"),
          std::string::npos)
          << wrong.out;
    }
  }
  // A name of neither vendor lists both vendors' names.
  const auto unknown = run_tool("info --model os3-128" + capture_args(kCaptures[0]));
  EXPECT_EQ(unknown.exit_code, 2) << unknown.out;
  EXPECT_NE(unknown.out.find("Ouster: os0, os1, os2"), std::string::npos) << unknown.out;
}

// An Ouster model for a capture without Ouster metadata is refused, not read as Velodyne packets.
TEST(CliOuster, AnOusterModelForAVelodyneCaptureIsRefused) {
  const std::string demo = std::string(LIDARTAG_SOURCE_DIR) + "/pcaps/demo.pcap";
  for (const char* command : {"info", "detect", "dump --out /nonexistent-never-created"}) {
    SCOPED_TRACE(command);
    const auto r = run_tool(std::string(command) + " --model os1-128 '" + demo + "'");
    EXPECT_EQ(r.exit_code, 2) << r.out;
    EXPECT_NE(r.out.find("model os1-128 is an Ouster sensor but"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("has no Ouster metadata"), std::string::npos) << r.out;
  }
}

// A cloud of an Ouster sensor without its ring field (another driver's PCD): --model os1-64 places
// its rings from the model's beam table, and the tag the capture shows is found there.
TEST(CliOuster, AnOusterModelPlacesTheRingsOfACloudWithoutARingField) {
  TempDir dir("ringless");
  fs::create_directories(dir.path);
  const std::string pcap = (dir.path / "os.pcap").string();
  auto r =
      run_tool("sim '" + std::string(LIDARTAG_SOURCE_DIR) + "/test/sim/ouster_scene.yaml' --out '" +
               pcap + "' --truth '" + (dir.path / "truth.json").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  r = run_tool("detect --json '" + pcap + "'", false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto frames = json_lines(r.out);
  ASSERT_FALSE(frames.empty());
  ASSERT_EQ(frames[0]["detections"].size(), 1u) << r.out;
  const auto& tag = frames[0]["detections"][0];
  r = run_tool("dump '" + pcap + "' --out '" + (dir.path / "dump").string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // The first whole frame's points (the PCD of the lowest number; detect's first line) as x y z
  // intensity only, in ascii.
  std::vector<fs::path> dumped;
  for (const auto& f : fs::directory_iterator(dir.path / "dump")) dumped.push_back(f.path());
  ASSERT_FALSE(dumped.empty());
  std::sort(dumped.begin(), dumped.end());
  const auto cloud = lidartag::velodyne::read_pcd_points(dumped.front().string());
  const fs::path ringless = dir.path / "ringless.pcd";
  {
    std::ofstream out(ringless);
    out << "FIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH "
        << cloud.size() << "\nHEIGHT 1\nPOINTS " << cloud.size() << "\nDATA ascii\n";
    out.precision(9);
    for (size_t k = 0; k < cloud.size(); ++k)
      out << cloud.field("x")[k] << ' ' << cloud.field("y")[k] << ' ' << cloud.field("z")[k] << ' '
          << cloud.field("intensity")[k] << '\n';
  }
  const std::string file = " '" + ringless.string() + "'";
  r = run_tool("detect" + file);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no ring field"), std::string::npos) << r.out;
  r = run_tool("info --json --model os1-64" + file, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto info = nlohmann::json::parse(r.out);
  EXPECT_EQ(info["scan"]["rings"], 64) << r.out;
  r = run_tool("detect --json --model OS1-64" + file, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto found = json_lines(r.out);
  ASSERT_EQ(found.size(), 1u) << r.out;
  ASSERT_EQ(found[0]["detections"].size(), 1u) << r.out;
  const auto& again = found[0]["detections"][0];
  EXPECT_EQ(again["id"], tag["id"]);
  for (size_t a = 0; a < 3; ++a)
    EXPECT_NEAR(again["position"][a].get<double>(), tag["position"][a].get<double>(), 0.02);
}

}  // namespace
