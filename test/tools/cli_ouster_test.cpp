// `lidartag info` on the real Ouster captures (../shared/captures/ouster; skipped when absent),
// run as a user would: metadata from --metadata or NAME.json beside NAME.pcap.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

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
};

// The captures' README: packets, frames; the IMU packets as in the files.
constexpr Expected kCaptures[] = {
    {"OS-1-32-G_v2.1.1_1024x10", nullptr, "LEGACY", 64, 0, 1, 1024},
    {"OS-2-32-U0_v2.0.0_1024x10", nullptr, "LEGACY", 64, 0, 1, 1024},
    {"OS-0-32-U1_v2.2.0_1024x10", nullptr, "RNG19_RFL8_SIG16_NIR16_DUAL", 64, 10, 1, 1024},
    {"OS-0-128-U1_v2.3.0_1024x10", nullptr, "RNG15_RFL8_NIR8", 64, 10, 1, 1024},
    {"OS-2-128-U1_v2.3.0_1024x10", nullptr, "RNG19_RFL8_SIG16_NIR16", 64, 10, 1, 1024},
    {"OS-1-128_v2.3.0_1024x10_lb_n3", "OS-1-128_v2.3.0_1024x10", "RNG15_RFL8_NIR8", 192, 30, 3,
     1024},
    {"OS-1-128_767798045_1024x10_20230712_120049", nullptr, "FUSA_RNG15_RFL8_NIR8_DUAL", 8, 2, 1,
     128},
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
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("data_format.columns_per_frame"), std::string::npos) << r.out;
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
