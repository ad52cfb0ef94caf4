// `lidartag info/dump/detect` on bags, run as a user would: a bag of the same packets as a pcap
// reports the same, and a bag without a VelodyneScan topic, or with an unknown --topic, is refused
// with one clear line and exit code 1.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "bag/bag_files.hpp"
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

TEST(BagCli, StartAndDurationCutABagAndAreRefusedForAPcap) {
  LIDARTAG_REQUIRE_BAGS();
  const std::string b = bag("rosbag2/vlp16_dual");
  const nlohmann::json whole = info(b);
  // Four VelodyneScan messages 0.1 s apart: [0.15 s, 0.35 s) holds the third and fourth.
  const auto r = run_tool("info --json --start 0.15 --duration 0.2 " + b, false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto cut = nlohmann::json::parse(r.out);
  EXPECT_EQ(cut["packets"]["data"].get<int>(), 301) << cut.dump();  // 151 + 150 of 603
  EXPECT_EQ(whole["packets"]["data"].get<int>(), 603);
  EXPECT_LT(cut["duration_s"].get<double>(), whole["duration_s"].get<double>());
  const auto pcap = run_tool("info --start 1 " + capture("vlp16_dual_nebula.pcap"));
  EXPECT_EQ(pcap.exit_code, 2);
  EXPECT_NE(pcap.out.find("take a ROS bag or MCAP file"), std::string::npos) << pcap.out;
  const auto negative = run_tool("info --start -1 " + b);
  EXPECT_NE(negative.exit_code, 0);
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
