#include "lidartag/driver/bag/bag_packet_source.hpp"

namespace lidartag::driver::bag {

// One open: the topic is chosen from the reader's connections (the constructor below) and the
// other topics' messages are passed over by connection.
BagPacketSource::BagPacketSource(const std::string& path, BagPacketSourceOptions options)
    : BagPacketSource(open_bag(path, ReaderOptions::window(options.start_s, options.duration_s)),
                      std::move(options), path) {}

BagPacketSource::BagPacketSource(std::unique_ptr<MessageReader> reader,
                                 BagPacketSourceOptions options, const std::string& path)
    : reader_(std::move(reader)), options_(std::move(options)) {
  // The topic asked for, else the one LiDAR topic (BagError listing the topics otherwise).
  options_.topic = choose_lidar_topic(reader_->connections(), options_.topic, path);
  for (const Connection& c : reader_->connections()) {
    const bool match = c.topic == options_.topic;
    if (match && message_kind(c.type) != MessageKind::kVelodyneScan)
      throw BagError(path + ": topic " + options_.topic + " holds " + c.type +
                     ", not velodyne_msgs/VelodyneScan packets");
    is_topic_.push_back(match);
  }
}

SourceStats BagPacketSource::stats() const {
  SourceStats s = stats_;
  s.outside_window = reader_->stats().outside_window;
  return s;
}

ReadStatus BagPacketSource::next(RawPacket& out, std::chrono::milliseconds /*timeout*/) {
  for (;;) {
    while (next_packet_ >= packets_.size()) {
      BagMessage m;
      if (!reader_->next(m)) return ReadStatus::kEnd;
      // Connections met after the open (a ROS 1 bag's chunks may add some) are judged by topic.
      const auto& connections = reader_->connections();
      for (size_t i = is_topic_.size(); i < connections.size(); ++i)
        is_topic_.push_back(connections[i].topic == options_.topic &&
                            message_kind(connections[i].type) == MessageKind::kVelodyneScan);
      if (m.connection >= is_topic_.size() || !is_topic_[m.connection]) {
        ++stats_.ignored;
        continue;
      }
      int64_t stamp = 0;
      const DecodeResult r =
          decode_velodyne_scan(m.data, connections[m.connection].encoding, stamp, packets_);
      next_packet_ = 0;
      if (r != DecodeResult::kOk) {
        // What was decoded before the damage is kept: those packets are whole.
        ++counts_.bad_messages;
        ++stats_.malformed;
        if (r == DecodeResult::kTruncated) ++stats_.truncated;
      }
      ++counts_.scans;
    }
    const StampedPacket& p = packets_[next_packet_++];
    // Stamps outside what a replay source accepts (a negative CDR time, or one past 2106) come
    // from corrupt messages: counted as malformed, as a pcap's are, so that packet times never
    // overflow.
    if (p.stamp_ns < 0 || p.stamp_ns >= kMaxReceiveTimeNs) {
      ++stats_.malformed;
      continue;
    }
    out.payload = p.payload;
    out.receive_time_ns = p.stamp_ns;
    out.source_ipv4 = 0;
    out.destination_port = options_.data_port;
    ++stats_.packets;
    stats_.bytes += p.payload.size();
    return ReadStatus::kPacket;
  }
}

}  // namespace lidartag::driver::bag
