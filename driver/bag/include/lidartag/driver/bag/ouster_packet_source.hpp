// A bag's Ouster packet messages (ouster_ros/PacketMsg) as a PacketSource: the lidar topic's
// packets delivered to the lidar port and its sibling IMU topic's to the IMU port, each message's
// receive time as the packet's, so that a bag takes the exact path a pcap of the same packets
// takes. The sensor's metadata JSON is read from the bag's metadata topic (std_msgs/String).
// Bytes only: decoding them is the Ouster driver's job.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver::bag {

struct OusterPacketSourceOptions {
  // The lidar packet topic; empty: the bag's one LiDAR topic (BagError listing them otherwise).
  std::string topic;
  uint16_t lidar_port = 7502;  // where lidar packets are delivered (the sensor's own ports)
  uint16_t imu_port = 7503;    // where the IMU topic's packets are delivered
  // Time window, seconds from the bag's first message (ReaderOptions::start_s, duration_s): only
  // the messages received in it are delivered. Defaults: the whole bag.
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();
};

// The IMU and metadata topics beside an Ouster lidar topic: same namespace ("/os_node0/" of
// "/os_node0/lidar_packets"), named imu_packets / metadata (or any topic of that namespace holding
// Ouster packets with "imu" in its name, or std_msgs/String with "metadata"); empty when absent.
std::string ouster_imu_topic(const std::vector<Connection>& connections,
                             const std::string& lidar_topic);
std::string ouster_metadata_topic(const std::vector<Connection>& connections,
                                  const std::string& lidar_topic);

// The metadata JSON text of the Ouster lidar topic `lidar_topic` (its first message on the
// metadata topic beside it). Throws BagError naming the bag when it has none.
std::string read_ouster_metadata(const std::string& path, const std::string& lidar_topic);

struct OusterPacketCounts {
  uint64_t lidar_messages = 0;  // messages of the lidar topic delivered
  uint64_t imu_messages = 0;    // of the IMU topic
  uint64_t bad_messages = 0;    // messages of either that did not decode (also in malformed)
};

class OusterPacketSource final : public PacketSource {
 public:
  // Opens `path` and picks the topic. Throws BagError: not a bag, no such topic, no LiDAR topic or
  // several (listing them), or a topic whose type is not an Ouster packet message.
  explicit OusterPacketSource(const std::string& path, OusterPacketSourceOptions options = {});

  // Never waits: kPacket, or kEnd once the bag is read (or damage stopped it: error()).
  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override;
  // Messages outside the time window are the reader's (MessageReader::stats()).
  SourceStats stats() const override;
  std::string error() const override { return reader_->error(); }

  const std::string& topic() const { return options_.topic; }
  const std::string& imu_topic() const { return imu_topic_; }
  const OusterPacketCounts& counts() const { return counts_; }

 private:
  std::unique_ptr<MessageReader> reader_;
  OusterPacketSourceOptions options_;
  std::string imu_topic_;
  std::vector<uint8_t> port_of_;  // per connection: 0 skipped, 1 lidar, 2 IMU
  SourceStats stats_{};
  OusterPacketCounts counts_;
};

}  // namespace lidartag::driver::bag
