// Every real bag in ../shared/captures/bags is recognised by content and read whole, with the exact
// message count of each topic (from its index or summary and from the reading alike).
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "bag/bag_files.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"

namespace lidartag::driver::bag {
namespace {

using testing::bag;

struct Expected {
  std::string file;
  BagFormat format;
  std::map<std::string, std::pair<std::string, uint64_t>> topics;  // topic -> type, messages
  uint64_t chunks;
};

const std::vector<Expected>& expected() {
  static const std::vector<Expected> e = {
      {"rosbag2/vlp16_dual",
       BagFormat::kRosbag2,
       {{"/velodyne_packets", {"velodyne_msgs/msg/VelodyneScan", 4}}},
       0},
      {"rosbag2/vlp32c",
       BagFormat::kRosbag2,
       {{"/sensing/lidar/front/velodyne_packets", {"velodyne_msgs/msg/VelodyneScan", 5}}},
       0},
      {"rosbag2/vls128",
       BagFormat::kRosbag2,
       {{"/velodyne_packets", {"velodyne_msgs/msg/VelodyneScan", 4}}},
       0},
      {"ros1/ouster_os0-128_512x10_packets.bag",
       BagFormat::kRos1,
       {{"/os_node0/lidar_packets", {"ouster_ros/PacketMsg", 32}},
        {"/os_node0/imu_packets", {"ouster_ros/PacketMsg", 10}},
        {"/os_node0/metadata", {"std_msgs/String", 1}}},
       1},
      {"ros1/luminar_pointcloud2_lz4.bag",
       BagFormat::kRos1,
       {{"/luminar_pointcloud", {"sensor_msgs/PointCloud2", 5}},
        {"/base_scan", {"sensor_msgs/LaserScan", 5}},
        {"/base_pose_ground_truth", {"nav_msgs/Odometry", 5}}},
       6},
      {"mcap/talker.mcap",
       BagFormat::kMcap,
       {{"/rosout", {"rcl_interfaces/msg/Log", 10}},
        {"/parameter_events", {"rcl_interfaces/msg/ParameterEvent", 0}},
        {"/topic", {"std_msgs/msg/String", 10}}},
       1},
      {"mcap/cdr_test_0.mcap",
       BagFormat::kMcap,
       {{"/test_topic", {"test_msgs/msg/BasicTypes", 3}},
        {"/array_topic", {"test_msgs/msg/Arrays", 4}}},
       1},
  };
  return e;
}

TEST(BagContainers, EveryRealBagReadWithExactCountsPerTopic) {
  LIDARTAG_REQUIRE_BAGS();
  for (const Expected& e : expected()) {
    SCOPED_TRACE(e.file);
    const std::string path = bag(e.file);
    EXPECT_EQ(detect_bag_format(path), e.format);
    const auto reader = open_bag(path);
    EXPECT_EQ(reader->format(), e.format);
    // Declared by the index / summary / database before anything is read.
    std::map<std::string, std::pair<std::string, uint64_t>> declared;
    for (const Connection& c : reader->connections()) declared[c.topic] = {c.type, c.count};
    EXPECT_EQ(declared, e.topics);
    // Read one by one.
    std::map<std::string, uint64_t> read;
    uint64_t total = 0, bytes = 0;
    int64_t last_time = 0;
    BagMessage m;
    while (reader->next(m)) {
      ASSERT_LT(m.connection, reader->connections().size());
      ++read[reader->connections()[m.connection].topic];
      ++total;
      bytes += m.data.size();
      EXPECT_GT(m.time_ns, 0);
      if (e.format == BagFormat::kRosbag2) {
        EXPECT_GE(m.time_ns, last_time);  // time order
      }
      last_time = m.time_ns;
    }
    uint64_t want = 0;
    for (const auto& [topic, type_count] : e.topics) {
      EXPECT_EQ(read[topic], type_count.second) << topic;
      want += type_count.second;
    }
    EXPECT_EQ(total, want);
    EXPECT_EQ(reader->stats().messages, want);
    EXPECT_EQ(reader->stats().bytes, bytes);
    EXPECT_EQ(reader->stats().chunks, e.chunks);
    EXPECT_EQ(reader->stats().skipped_chunks, 0u);
    EXPECT_EQ(reader->stats().skipped_records, 0u);
    EXPECT_EQ(reader->stats().truncated, 0u);
    EXPECT_EQ(reader->error(), "");
  }
}

TEST(BagContainers, RecognisedByContentNotByName) {
  LIDARTAG_REQUIRE_BAGS();
  testing::TempDir dir;
  // Each container under a misleading name is still what its bytes say.
  const std::string ros1 = dir.file("ouster.pcap"), mcap = dir.file("talker.bag");
  testing::write_bytes(ros1, testing::read_bytes(bag("ros1/ouster_os0-128_512x10_packets.bag")));
  testing::write_bytes(mcap, testing::read_bytes(bag("mcap/talker.mcap")));
  EXPECT_EQ(detect_bag_format(ros1), BagFormat::kRos1);
  EXPECT_EQ(detect_bag_format(mcap), BagFormat::kMcap);
  // A rosbag2 folder, its metadata.yaml and its .db3 alone.
  EXPECT_EQ(detect_bag_format(bag("rosbag2/vlp32c")), BagFormat::kRosbag2);
  EXPECT_EQ(detect_bag_format(bag("rosbag2/vlp32c/metadata.yaml")), BagFormat::kRosbag2);
  EXPECT_EQ(detect_bag_format(bag("rosbag2/vlp32c/1713492677464078412_0.db3")),
            BagFormat::kRosbag2);
  EXPECT_EQ(open_bag(bag("rosbag2/vlp32c/1713492677464078412_0.db3"))->connections().at(0).count,
            5u);
  // Not bags: a pcap, a README, a folder of bags, a missing path.
  EXPECT_EQ(detect_bag_format(testing::capture("vlp32c_nebula_fov.pcap")), BagFormat::kNone);
  EXPECT_EQ(detect_bag_format(bag("README.md")), BagFormat::kNone);
  EXPECT_EQ(detect_bag_format(bag("ros1")), BagFormat::kNone);
  EXPECT_EQ(detect_bag_format(dir.file("missing")), BagFormat::kNone);
  EXPECT_THROW(open_bag(testing::capture("vlp32c_nebula_fov.pcap")), BagError);
}

TEST(BagContainers, TopicFilterDeliversOnlyThoseTopics) {
  LIDARTAG_REQUIRE_BAGS();
  ReaderOptions options;
  options.topics = {"/os_node0/imu_packets", "/os_node0/metadata"};
  const auto reader = open_bag(bag("ros1/ouster_os0-128_512x10_packets.bag"), options);
  std::map<std::string, int> read;
  BagMessage m;
  while (reader->next(m)) ++read[reader->connections()[m.connection].topic];
  EXPECT_EQ(read,
            (std::map<std::string, int>{{"/os_node0/imu_packets", 10}, {"/os_node0/metadata", 1}}));
}

TEST(BagContainers, VlsBagWithEmptySerializationFormatKeepsItsOwnTimestamps) {
  LIDARTAG_REQUIRE_BAGS();
  // Its serialization_format column is empty (read as CDR); its metadata.yaml says 2021, its
  // messages 2020: the messages' times are kept.
  const auto reader = open_bag(bag("rosbag2/vls128"));
  ASSERT_EQ(reader->connections().size(), 1u);
  EXPECT_EQ(reader->connections()[0].encoding, Encoding::kCdr);
  BagMessage m;
  ASSERT_TRUE(reader->next(m));
  constexpr int64_t k2021 = 1609459200LL * 1'000'000'000;
  EXPECT_LT(m.time_ns, k2021);
  std::vector<StampedPacket> packets;
  int64_t stamp = 0;
  ASSERT_EQ(decode_velodyne_scan(m.data, Encoding::kCdr, stamp, packets), DecodeResult::kOk);
  EXPECT_GE(packets.size(), 383u);
  EXPECT_LE(packets.size(), 604u);
}

TEST(BagContainers, OusterPacketsAndMetadataRecognised) {
  LIDARTAG_REQUIRE_BAGS();
  const auto reader = open_bag(bag("ros1/ouster_os0-128_512x10_packets.bag"));
  EXPECT_EQ(lidar_topics(reader->connections()),
            std::vector<std::string>{"/os_node0/lidar_packets"});
  std::map<std::string, std::map<size_t, int>> sizes;  // topic -> packet size -> count
  std::string metadata;
  BagMessage m;
  while (reader->next(m)) {
    const Connection& c = reader->connections()[m.connection];
    if (message_kind(c.type) == MessageKind::kOusterPacket) {
      std::span<const uint8_t> packet;
      ASSERT_EQ(decode_ouster_packet(m.data, c.encoding, packet), DecodeResult::kOk);
      ++sizes[c.topic][packet.size()];
    } else {
      ASSERT_EQ(message_kind(c.type), MessageKind::kString);
      std::string_view text;
      ASSERT_EQ(decode_string(m.data, c.encoding, text), DecodeResult::kOk);
      metadata = text;
    }
  }
  EXPECT_EQ(sizes["/os_node0/lidar_packets"], (std::map<size_t, int>{{8448, 32}}));
  EXPECT_EQ(sizes["/os_node0/imu_packets"], (std::map<size_t, int>{{48, 10}}));
  EXPECT_NE(metadata.find("OS-0-128"), std::string::npos);
  EXPECT_NE(metadata.find("512x10"), std::string::npos);
  EXPECT_EQ(metadata.front(), '{');
}

TEST(BagContainers, TopicChoice) {
  LIDARTAG_REQUIRE_BAGS();
  const auto luminar = open_bag(bag("ros1/luminar_pointcloud2_lz4.bag"));
  EXPECT_EQ(choose_lidar_topic(luminar->connections(), "", "l.bag"), "/luminar_pointcloud");
  EXPECT_EQ(choose_lidar_topic(luminar->connections(), "/base_scan", "l.bag"), "/base_scan");
  try {
    (void)choose_lidar_topic(luminar->connections(), "/nope", "l.bag");
    ADD_FAILURE() << "no error for a missing topic";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find("no topic /nope"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/luminar_pointcloud"), std::string::npos) << e.what();
  }
  // No LiDAR topic: the bag's topics listed.
  const auto talker = open_bag(bag("mcap/talker.mcap"));
  try {
    (void)choose_lidar_topic(talker->connections(), "", "talker.mcap");
    ADD_FAILURE() << "no error without a LiDAR topic";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find("no LiDAR topic"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/rosout (rcl_interfaces/msg/Log, 10 messages)"),
              std::string::npos)
        << e.what();
  }
  // Several: the candidates listed, the others not.
  std::vector<Connection> two = luminar->connections();
  two.push_back({"/velodyne_packets", "velodyne_msgs/VelodyneScan", Encoding::kRos1, 3});
  try {
    (void)choose_lidar_topic(two, "", "two.bag");
    ADD_FAILURE() << "no error with two LiDAR topics";
  } catch (const BagError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("several LiDAR topics"), std::string::npos) << what;
    EXPECT_NE(what.find("/velodyne_packets"), std::string::npos) << what;
    EXPECT_NE(what.find("/luminar_pointcloud"), std::string::npos) << what;
    EXPECT_EQ(what.find("/base_scan"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace lidartag::driver::bag
