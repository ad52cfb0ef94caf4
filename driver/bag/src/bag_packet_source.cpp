#include "lidartag/driver/bag/bag_packet_source.hpp"

namespace lidartag::driver::bag {

// One open: the topic is chosen from the reader's connections (the constructor below) and the
// other topics' messages are passed over by connection.
BagPacketSource::BagPacketSource(const std::string& path, BagPacketSourceOptions options)
    : BagPacketSource(open_bag(path), std::move(options), path) {}

BagPacketSource::BagPacketSource(std::unique_ptr<MessageReader> reader,
                                 BagPacketSourceOptions options, const std::string& path)
    : reader_(std::move(reader)), options_(std::move(options)) {
  if (options_.topic.empty())
    options_.topic = choose_lidar_topic(reader_->connections(), options_.topic, path);
  bool found = false;
  for (const Connection& c : reader_->connections()) {
    const bool match = c.topic == options_.topic;
    is_topic_.push_back(match);
    if (match && message_kind(c.type) != MessageKind::kVelodyneScan)
      throw BagError(path + ": topic " + options_.topic + " holds " + c.type +
                     ", not velodyne_msgs/VelodyneScan packets");
    found = found || match;
  }
  if (!found) throw BagError(path + ": no topic " + options_.topic);
}

ReadStatus BagPacketSource::next(RawPacket& out, std::chrono::milliseconds /*timeout*/) {
  while (next_packet_ >= packets_.size()) {
    BagMessage m;
    if (!reader_->next(m)) return ReadStatus::kEnd;
    if (m.connection >= is_topic_.size() || !is_topic_[m.connection]) {
      ++stats_.ignored;
      continue;
    }
    int64_t stamp = 0;
    const DecodeResult r = decode_velodyne_scan(
        m.data, reader_->connections()[m.connection].encoding, stamp, packets_);
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
  out.payload = p.payload;
  out.receive_time_ns = p.stamp_ns;
  out.source_ipv4 = 0;
  out.destination_port = options_.data_port;
  ++stats_.packets;
  stats_.bytes += p.payload.size();
  return ReadStatus::kPacket;
}

}  // namespace lidartag::driver::bag
