// `lidartag info/dump/detect` on bags, run as a user would: a bag of the same packets as a pcap
// reports the same, and a bag without a VelodyneScan topic, or with an unknown --topic, is refused
// with one clear line and exit code 1.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "bag/bag_files.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "tools/run_tool.hpp"

namespace lidartag::driver::bag {
namespace {

using lidartag::testing::run_tool;
using testing::bag;
using testing::capture;

nlohmann::json info(const std::string& path) {
  const auto r = run_tool("info --json " + path, false);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  return nlohmann::json::parse(r.out);
}

TEST(BagCli, InfoOnEachRosbag2MatchesItsPcap) {
  LIDARTAG_REQUIRE_BAGS();
  for (const auto& [b, p] : std::vector<std::pair<std::string, std::string>>{
           {"rosbag2/vlp16_dual", "vlp16_dual_nebula.pcap"},
           {"rosbag2/vlp32c", "vlp32c_nebula_fov.pcap"},
           {"rosbag2/vls128", "vls128_nebula.pcap"}}) {
    SCOPED_TRACE(b);
    nlohmann::json from_bag = info(bag(b)), from_pcap = info(capture(p));
    ASSERT_GT(from_pcap["rotations"]["total"].get<int>(), 1);
    for (const char* key : {"model", "return_mode", "rotations", "packets", "rpm"})
      EXPECT_EQ(from_bag[key], from_pcap[key]) << key;
    // The pcaps keep microseconds, the bags' packet stamps nanoseconds (the rotations' stamps
    // come from the packets' own clock and are equal: test_bag_velodyne.cpp).
    EXPECT_NEAR(from_bag["duration_s"].get<double>(), from_pcap["duration_s"].get<double>(), 1e-6);
  }
}

TEST(BagCli, TopicOptionAndRefusals) {
  LIDARTAG_REQUIRE_BAGS();
  auto r = run_tool("info --topic /sensing/lidar/front/velodyne_packets " + bag("rosbag2/vlp32c"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  r = run_tool("info --topic /nope " + bag("rosbag2/vlp32c"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no topic /nope; its topics: /sensing/lidar/front/velodyne_packets"),
            std::string::npos)
      << r.out;
  r = run_tool("info " + bag("mcap/talker.mcap"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no LiDAR topic"), std::string::npos) << r.out;
  // A topic that holds neither packets nor clouds is refused by name.
  r = run_tool("info --topic /base_scan " + bag("ros1/luminar_pointcloud2_lz4.bag"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("not velodyne_msgs/VelodyneScan"), std::string::npos) << r.out;
}

TEST(BagCli, InfoOfAPointCloud2TopicCountsItsCloudsAndPoints) {
  LIDARTAG_REQUIRE_BAGS();
  const std::string luminar = bag("ros1/luminar_pointcloud2_lz4.bag");
  nlohmann::json j = info(luminar);
  EXPECT_EQ(j["topic"], "/luminar_pointcloud");
  EXPECT_EQ(j["clouds"].get<int>(), 5);
  EXPECT_EQ(j["points"].get<int>(), 35707 + 36055 + 36267 + 36457 + 36336);
  EXPECT_EQ(j["points_min"].get<int>(), 35707);
  EXPECT_EQ(j["fields"], "x y z intensity time_sec time_nsec laser_id");
  const auto r = run_tool("info --json --start 0.15 --duration 0.2 " + luminar, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["clouds"].get<int>(), 2);
  EXPECT_EQ(j["outside_window"].get<int>(), 3);
  EXPECT_EQ(j["first_stamp_ns"].get<int64_t>(), 1583971570215200989);
}

size_t pcd_files(const std::string& folder) {
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(folder))
    files += e.path().extension() == ".pcd" ? 1u : 0u;
  return files;
}

TEST(BagCli, DumpAndRenderTakeAPointCloud2Topic) {
  LIDARTAG_REQUIRE_BAGS();
  testing::TempDir dir;
  const std::string luminar = bag("ros1/luminar_pointcloud2_lz4.bag");
  auto r = run_tool("dump " + luminar + " --out " + dir.file("all"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(pcd_files(dir.file("all")), 5u);  // one per cloud
  EXPECT_NE(r.out.find("wrote 5 PCD files"), std::string::npos) << r.out;
  // The clouds 0.1 s apart: [0.15 s, 0.35 s) holds the third and fourth.
  r = run_tool("dump --start 0.15 --duration 0.2 " + luminar + " --out " + dir.file("window"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(pcd_files(dir.file("window")), 2u);
  r = run_tool("render --rotation 4 -o " + dir.file("view") + " " + luminar);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(std::filesystem::exists(dir.file("view-rotation4.png"))) << r.out;
  r = run_tool("render --rotation 7 -o " + dir.file("view") + " " + luminar);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.out.find("has clouds 0-4"), std::string::npos) << r.out;
}

TEST(BagCli, StartAndDurationCutABagAndAPcap) {
  LIDARTAG_REQUIRE_BAGS();
  const std::string b = bag("rosbag2/vlp16_dual");
  const nlohmann::json whole = info(b);
  // Four VelodyneScan messages 0.1 s apart: [0.15 s, 0.35 s) holds the third and fourth.
  auto r = run_tool("info --json --start 0.15 --duration 0.2 " + b, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto cut = nlohmann::json::parse(r.out);
  EXPECT_EQ(cut["packets"]["data"].get<int>(), 301) << cut.dump();  // 151 + 150 of 603
  EXPECT_EQ(cut["outside_window"].get<int>(), 2);                   // messages
  EXPECT_EQ(whole["packets"]["data"].get<int>(), 603);
  EXPECT_LT(cut["duration_s"].get<double>(), whole["duration_s"].get<double>());
  const auto negative = run_tool("info --start -1 " + b);
  EXPECT_NE(negative.exit_code, 0);

  // A pcap: from its first packet; the packets in the window counted here from the pcap itself.
  const std::string pcap = capture("vlp16_dual_nebula.pcap");
  uint64_t data = 0, outside = 0, n = 0;
  {
    PcapSource source(pcap);
    RawPacket p;
    int64_t first = 0;
    while (source.next(p, std::chrono::milliseconds(0)) == ReadStatus::kPacket) {
      if (n++ == 0) first = p.receive_time_ns;
      const double t = static_cast<double>(p.receive_time_ns - first) * 1e-9;
      if (t >= 0.15 && t < 0.35)
        data += p.destination_port == kDefaultDataPort ? 1 : 0;
      else
        ++outside;
    }
  }
  r = run_tool("info --json --start 0.15 --duration 0.2 " + pcap, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto pcap_cut = nlohmann::json::parse(r.out);
  EXPECT_EQ(pcap_cut["packets"]["data"].get<uint64_t>(), data);
  EXPECT_EQ(pcap_cut["outside_window"].get<uint64_t>(), outside);
  EXPECT_GT(outside, 0u);
  const nlohmann::json pcap_whole = info(pcap);
  EXPECT_FALSE(pcap_whole.contains("outside_window"));
  EXPECT_LT(pcap_cut["rotations"]["total"].get<int>(), pcap_whole["rotations"]["total"].get<int>());
  r = run_tool("info --start 0.15 --duration 0.2 " + pcap);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("(" + std::to_string(outside) + " packets outside --start/--duration)"),
            std::string::npos)
      << r.out;
  // dump and detect take it too: fewer rotations than the whole pcap.
  testing::TempDir dir;
  r = run_tool("dump --partial --start 0.15 --duration 0.2 " + pcap + " --out " + dir.file("w"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.file("w")))
    files += e.is_regular_file();
  EXPECT_EQ(files, pcap_cut["rotations"]["total"].get<size_t>());
  // A window past the capture's end: nothing to detect in, the message says why.
  r = run_tool("detect --start 100 " + pcap);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find(std::to_string(n) + " outside --start/--duration"), std::string::npos)
      << r.out;
}

// A ROS 1 bag of Ouster OS0-128 packets with its metadata topic: every command decodes it as the
// daemon does, one whole 512-column frame, the IMU topic's packets counted apart.
TEST(BagCli, AnOusterPacketBagInEveryCommand) {
  LIDARTAG_REQUIRE_BAGS();
  const std::string b = bag("ros1/ouster_os0-128_512x10_packets.bag");
  const nlohmann::json j = info(b);
  EXPECT_EQ(j["vendor"], "ouster");
  EXPECT_EQ(j["profile"], "RNG15_RFL8_NIR8");
  EXPECT_EQ(j["beams"], 128);
  EXPECT_EQ(j["lidar_mode"], "512x10");
  EXPECT_EQ(j["packets"]["lidar"], 32);
  EXPECT_EQ(j["packets"]["imu"], 10);
  EXPECT_EQ(j["frames"]["total"], 1);
  EXPECT_EQ(j["frames"]["complete"], 1);
  EXPECT_EQ(j["frames"]["most_columns"], 512);
  EXPECT_NE(j["metadata"].get<std::string>().find("its metadata topic"), std::string::npos);
  for (const auto& [status, count] : j["refused"].items()) EXPECT_EQ(count, 0) << status;
  const int points = j["frames"]["points"].get<int>();
  EXPECT_GT(points, 10000);

  testing::TempDir dir;
  auto r = run_tool("dump " + b + " --out " + dir.file("out"));
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(pcd_files(dir.file("out")), 1u);
  EXPECT_NE(r.out.find("wrote 1 PCD files (" + std::to_string(points) + " points)"),
            std::string::npos)
      << r.out;
  r = run_tool("detect --json " + b, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto rotation = nlohmann::json::parse(r.out.substr(0, r.out.find('\n')));
  EXPECT_EQ(rotation["points"].get<int>(), points);
  EXPECT_EQ(rotation["detections"].size(), 0u);
  r = run_tool("render -o " + dir.file("view") + " " + b);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  bool png = false;
  for (const auto& e : std::filesystem::directory_iterator(dir.file("")))
    png |= e.path().extension() == ".png";
  EXPECT_TRUE(png) << r.out;
  // Velodyne's options are refused for it, naming the option.
  r = run_tool("detect --cut 90 " + b);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("--cut is for Velodyne captures"), std::string::npos) << r.out;
}

TEST(BagCli, DetectRunsOnEveryPointCloudOfALuminarBag) {
  LIDARTAG_REQUIRE_BAGS();
  // Five PointCloud2 clouds (laser_id as the ring field), no tags in them.
  const auto r = run_tool("detect --json " + bag("ros1/luminar_pointcloud2_lz4.bag"), false);
  EXPECT_EQ(r.exit_code, 0);
  std::vector<nlohmann::json> rotations;
  size_t start = 0;
  for (size_t end = r.out.find('\n'); end != std::string::npos;
       start = end + 1, end = r.out.find('\n', start))
    rotations.push_back(nlohmann::json::parse(r.out.substr(start, end - start)));
  ASSERT_EQ(rotations.size(), 5u) << r.out;
  for (size_t i = 0; i < rotations.size(); ++i) {
    EXPECT_EQ(rotations[i]["detections"].size(), 0u);
    EXPECT_GT(rotations[i]["points"].get<int>(), 0);
  }
}

TEST(BagCli, DumpOfABagWritesItsRotations) {
  LIDARTAG_REQUIRE_BAGS();
  testing::TempDir dir;
  const auto r = run_tool("dump " + bag("rosbag2/vlp32c") + " --out " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 0) << r.out;
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.file("out")))
    files += e.path().extension() == ".pcd" ? 1u : 0u;
  EXPECT_EQ(files, info(bag("rosbag2/vlp32c"))["rotations"]["complete"].get<size_t>());
}

}  // namespace
}  // namespace lidartag::driver::bag
