#include "lidartag/driver/bag/ouster_packet_source.hpp"

#include "lidartag/driver/bag/messages.hpp"

namespace lidartag::driver::bag {
namespace {

// "/os_node0/" of "/os_node0/lidar_packets" ("" for a topic without a namespace).
std::string namespace_of(const std::string& topic) {
  const size_t slash = topic.rfind('/');
  return slash == std::string::npos ? std::string() : topic.substr(0, slash + 1);
}

std::string sibling(const std::vector<Connection>& connections, const std::string& lidar_topic,
                    MessageKind kind, std::string_view word) {
  const std::string ns = namespace_of(lidar_topic);
  for (const Connection& c : connections) {
    if (c.topic == lidar_topic || message_kind(c.type) != kind) continue;
    if (c.topic.compare(0, ns.size(), ns) != 0) continue;
    if (c.topic.find(word, ns.size()) != std::string::npos) return c.topic;
  }
  return {};
}

}  // namespace

std::string ouster_imu_topic(const std::vector<Connection>& connections,
                             const std::string& lidar_topic) {
  return sibling(connections, lidar_topic, MessageKind::kOusterPacket, "imu");
}

std::string ouster_metadata_topic(const std::vector<Connection>& connections,
                                  const std::string& lidar_topic) {
  return sibling(connections, lidar_topic, MessageKind::kString, "metadata");
}

std::string read_ouster_metadata(const std::string& path, const std::string& lidar_topic) {
  std::string topic;
  {
    const auto probe = open_bag(path);
    topic = ouster_metadata_topic(probe->connections(), lidar_topic);
  }
  if (topic.empty())
    throw BagError(path + ": no metadata topic beside " + lidar_topic +
                   " (a std_msgs/String topic named like " +
                   lidar_topic.substr(0, lidar_topic.rfind('/') + 1) +
                   "metadata): give the sensor's metadata JSON file");
  ReaderOptions options;
  options.topics = {topic};
  const auto reader = open_bag(path, options);
  BagMessage m;
  while (reader->next(m)) {
    const auto& c = reader->connections()[m.connection];
    if (c.topic != topic) continue;
    std::string_view text;
    if (decode_string(m.data, c.encoding, text) == DecodeResult::kOk) return std::string(text);
  }
  throw BagError(path + ": its metadata topic " + topic + " holds no readable message" +
                 (reader->error().empty() ? std::string() : " (" + reader->error() + ")"));
}

OusterPacketSource::OusterPacketSource(const std::string& path, OusterPacketSourceOptions options)
    : reader_(open_bag(path, ReaderOptions::window(options.start_s, options.duration_s))),
      options_(std::move(options)) {
  const auto& connections = reader_->connections();
  options_.topic = choose_lidar_topic(connections, options_.topic, path);
  for (const Connection& c : connections) {
    if (c.topic == options_.topic && message_kind(c.type) != MessageKind::kOusterPacket)
      throw BagError(path + ": topic " + options_.topic + " holds " + c.type +
                     ", not ouster_ros/PacketMsg packets");
  }
  imu_topic_ = ouster_imu_topic(connections, options_.topic);
}

SourceStats OusterPacketSource::stats() const {
  SourceStats s = stats_;
  s.outside_window = reader_->stats().outside_window;
  return s;
}

ReadStatus OusterPacketSource::next(RawPacket& out, std::chrono::milliseconds /*timeout*/) {
  BagMessage m;
  while (reader_->next(m)) {
    // Connections met after the open (a ROS 1 bag's chunks may add some) are judged by topic.
    const auto& connections = reader_->connections();
    for (size_t i = port_of_.size(); i < connections.size(); ++i) {
      const Connection& c = connections[i];
      const bool packets = message_kind(c.type) == MessageKind::kOusterPacket;
      port_of_.push_back(!packets                                       ? 0
                         : c.topic == options_.topic                    ? 1
                         : c.topic == imu_topic_ && !imu_topic_.empty() ? 2
                                                                        : 0);
    }
    const uint8_t port = m.connection < port_of_.size() ? port_of_[m.connection] : 0;
    if (port == 0) {
      ++stats_.ignored;
      continue;
    }
    std::span<const uint8_t> payload;
    if (decode_ouster_packet(m.data, connections[m.connection].encoding, payload) !=
        DecodeResult::kOk) {
      ++counts_.bad_messages;
      ++stats_.malformed;
      continue;
    }
    // Times outside what a replay source accepts come from corrupt messages (as a pcap's).
    if (m.time_ns < 0 || m.time_ns >= kMaxReceiveTimeNs) {
      ++stats_.malformed;
      continue;
    }
    ++(port == 1 ? counts_.lidar_messages : counts_.imu_messages);
    out.payload = payload;
    out.receive_time_ns = m.time_ns;
    out.source_ipv4 = 0;
    out.destination_port = port == 1 ? options_.lidar_port : options_.imu_port;
    ++stats_.packets;
    stats_.bytes += payload.size();
    return ReadStatus::kPacket;
  }
  return ReadStatus::kEnd;
}

}  // namespace lidartag::driver::bag
