// Runs build/bin/lidartag info/dump on the real captures and checks what it reports and writes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "lidartag/driver/velodyne/io/pcd.hpp"
#include "run_tool.hpp"

namespace {

namespace fs = std::filesystem;
const std::string kCaptures = LIDARTAG_SHARED_DIR "/captures/";

using Result = lidartag::testing::ToolResult;
using lidartag::testing::run_tool;

#define REQUIRE_CAPTURE(name)                     \
  const std::string capture = kCaptures + (name); \
  if (!fs::exists(capture)) GTEST_SKIP() << "capture not available: " << capture

nlohmann::json info_json(const std::string& capture) {
  const Result r = run_tool("info --json " + capture);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return nlohmann::json::parse(r.out, nullptr, false);
}

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("lidartag_cli_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

TEST(CliInfo, Vlp16WithGpsReportsModelModePacketsAndGps) {
  REQUIRE_CAPTURE("vlp16_mrpt_gps.pcap");
  const Result r = run_tool("info " + capture);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("model:          vlp16 (from product byte)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("return mode:    strongest"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("data 293, position 57, ignored 0, truncated 0, malformed 0"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("PPS locked, valid GPRMC 57"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("last nmea:      $GPRMC,"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("MISMATCH"), std::string::npos) << r.out;
}

TEST(CliInfo, JsonOfEveryCaptureMatchesItsReadme) {
  struct Expect {
    const char* file;
    const char* model;
    const char* mode;
    uint64_t data, position;
    uint64_t min_complete;
  };
  const Expect expected[] = {
      {"vlp16_mrpt_gps.pcap", "vlp16", "strongest", 293, 57, 2},
      {"vlp16_rlu.pcap", "vlp16", "strongest", 84, 0, 0},
      {"vlp16_dual_nebula.pcap", "vlp16", "dual", 603, 0, 3},
      {"vlp32c_nebula_fov.pcap", "vlp32c", "strongest", 379, 0, 3},
      {"vls128_nebula.pcap", "vls128", "strongest", 2193, 0, 3},
      {"hdl32e_mrpt.pcap", "hdl32e", "strongest", 500, 0, 1},
      {"hdl32e_rlu_gps.pcap", "hdl32e", "strongest", 876, 100, 3},
  };
  size_t checked = 0;
  for (const Expect& e : expected) {
    const std::string capture = kCaptures + e.file;
    if (!fs::exists(capture)) continue;
    SCOPED_TRACE(e.file);
    const nlohmann::json j = info_json(capture);
    ASSERT_FALSE(j.is_discarded());
    EXPECT_EQ(j["model"], e.model);
    EXPECT_EQ(j["model_from"], "product byte");
    EXPECT_EQ(j["model_mismatch"], "");
    EXPECT_EQ(j["return_mode"], e.mode);
    EXPECT_EQ(j["packets"]["data"], e.data);
    EXPECT_EQ(j["packets"]["decoded"], e.data);
    EXPECT_EQ(j["packets"]["position"], e.position);
    EXPECT_GE(j["rotations"]["complete"].get<uint64_t>(), e.min_complete);
    EXPECT_EQ(
        j["rotations"]["total"].get<uint64_t>(),
        j["rotations"]["complete"].get<uint64_t>() + j["rotations"]["incomplete"].get<uint64_t>());
    EXPECT_EQ(j["missing_packets"], 0u);
    EXPECT_NEAR(j["rpm"].get<double>(), 600.0, 150.0);
    ++checked;
  }
  if (checked == 0) GTEST_SKIP() << "no captures in " << kCaptures;
}

TEST(CliInfo, DualCaptureHasFourRotationsOfPackets) {
  REQUIRE_CAPTURE("vlp16_dual_nebula.pcap");
  const nlohmann::json j = info_json(capture);
  // 603 packets = 4 rotations at 600 rpm: cut at 180 deg that is 3 whole ones and two halves.
  EXPECT_EQ(j["rotations"]["complete"], 3u);
  EXPECT_EQ(j["rotations"]["total"], 5u);
  EXPECT_NEAR(j["duration_s"].get<double>(), 0.4, 0.01);
}

TEST(CliInfo, RestrictedFieldOfViewShowsGaps) {
  REQUIRE_CAPTURE("vlp32c_nebula_fov.pcap");
  const nlohmann::json j = info_json(capture);
  EXPECT_GE(j["fov_gaps"].get<uint64_t>(), 4u);  // at least one per rotation
  EXPECT_EQ(j["azimuth_jumps"], 0u);
}

TEST(CliInfo, GivenModelContradictingTheTimingIsShown) {
  REQUIRE_CAPTURE("vlp16_rlu.pcap");
  const Result r = run_tool("info --model vlp32c " + capture);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("model:          vlp32c (from --model)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("MISMATCH:     configured model vlp32c but the packets' product byte and "
                       "timing (1327 us per packet) fit vlp16"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("MISMATCH"), r.out.rfind("MISMATCH")) << "reported once: " << r.out;
}

TEST(CliDump, WritesOnePcdPerCompleteRotation) {
  REQUIRE_CAPTURE("vlp16_dual_nebula.pcap");
  TempDir dir;
  const std::string out = dir.str() + "/nested/scans";
  const Result r = run_tool("dump " + capture + " --out " + out);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  size_t files = 0, points = 0;
  // Named by the rotation's number: the first complete one is rotation 1 (0 is the partial one).
  EXPECT_FALSE(fs::exists(out + "/rotation_000000.pcd"));
  for (; fs::exists(out + "/rotation_00000" + std::to_string(files + 1) + ".pcd"); ++files) {
    const auto cloud =
        lidartag::velodyne::read_pcd(out + "/rotation_00000" + std::to_string(files + 1) + ".pcd");
    EXPECT_EQ(cloud.rotation.sequence, files + 1);
    EXPECT_GT(cloud.size(), 10000u);
    const auto& ring = cloud.field("ring");
    EXPECT_EQ(*std::max_element(ring.begin(), ring.end()), 15.0);
    const auto& type = cloud.field("return_type");
    EXPECT_TRUE(std::any_of(type.begin(), type.end(), [](double t) { return t == 2.0; }))
        << "dual mode: some last-return points";
    const auto& time = cloud.field("time");
    EXPECT_LT(*std::max_element(time.begin(), time.end()), 0.11);  // one rotation at 600 rpm
    points += cloud.size();
  }
  EXPECT_EQ(files, 3u);
  EXPECT_NE(r.out.find("wrote 3 PCD files (" + std::to_string(points) + " points)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("skipped 2 incomplete"), std::string::npos) << r.out;
}

TEST(CliDump, PartialAlsoWritesTheIncompleteRotations) {
  REQUIRE_CAPTURE("vlp16_dual_nebula.pcap");
  TempDir dir;
  const Result r = run_tool("dump --partial " + capture + " --out " + dir.str());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  size_t points = 0;
  for (int i = 0; i < 5; ++i) {
    const std::string file = dir.str() + "/rotation_00000" + std::to_string(i) + ".pcd";
    ASSERT_TRUE(fs::exists(file)) << file;
    points += lidartag::velodyne::read_pcd(file).size();
  }
  EXPECT_FALSE(fs::exists(dir.str() + "/rotation_000005.pcd"));
  const nlohmann::json j = info_json(capture);
  EXPECT_EQ(points, j["rotations"]["points"].get<size_t>());
}

TEST(CliErrors, UsageAndConfigurationErrorsExitTwoRuntimeErrorsExitOne) {
  EXPECT_EQ(run_tool("").exit_code, 2);
  EXPECT_EQ(run_tool("no-such-command").exit_code, 2);
  // A missing input is an input that cannot be read (docs/tools.md): 1, one prefixed line.
  const auto missing = run_tool("info /nonexistent-lidartag/x.pcap");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(missing.out.rfind("lidartag: error: ", 0), 0u) << missing.out;
  EXPECT_NE(missing.out.find("/nonexistent-lidartag/x.pcap"), std::string::npos) << missing.out;
  const auto unknown = run_tool("info --no-such-option /dev/null");
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_EQ(unknown.out.rfind("lidartag: error: ", 0), 0u) << unknown.out;
  EXPECT_EQ(run_tool("--help").exit_code, 0);
  REQUIRE_CAPTURE("vlp16_rlu.pcap");
  const Result bad_model = run_tool("info --model vlp99 " + capture);
  EXPECT_EQ(bad_model.exit_code, 2);
  EXPECT_NE(bad_model.out.find("vlp16, puck-hires, vlp32c, hdl32e, vls128"), std::string::npos)
      << bad_model.out;
  EXPECT_EQ(run_tool("dump " + capture).exit_code, 2);  // --out is required
  TempDir dir;
  fs::create_directories(dir.str());
  const std::string yaml = dir.str() + "/bad.yaml";
  {
    std::FILE* f = std::fopen(yaml.c_str(), "w");
    std::fputs("lasers: 3\n", f);
    std::fclose(f);
  }
  const Result bad_calibration =
      run_tool("info --model vlp16 --calibration " + yaml + " " + capture);
  EXPECT_EQ(bad_calibration.exit_code, 2);  // a configuration file
  EXPECT_EQ(bad_calibration.out.rfind("lidartag: error: calibration file '" + yaml, 0), 0u)
      << bad_calibration.out;
  const Result not_pcap = run_tool("info " + yaml);
  EXPECT_EQ(not_pcap.exit_code, 1);
  EXPECT_EQ(not_pcap.out.rfind("lidartag: error: cannot open capture", 0), 0u) << not_pcap.out;
}

}  // namespace
