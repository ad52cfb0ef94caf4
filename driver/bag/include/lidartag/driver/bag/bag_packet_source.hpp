// A bag's VelodyneScan messages as a PacketSource: each VelodynePacket's 1206 bytes delivered as a
// UDP payload to the data port, its stamp as the receive time, so that a bag takes the exact path a
// pcap of the same packets takes (decoder, batcher, rotations).
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver::bag {

struct BagPacketSourceOptions {
  // The VelodyneScan topic; empty: the bag's one LiDAR topic (BagError when there are several,
  // listing them, or none).
  std::string topic;
  // Port the packets are delivered to (what the reader takes for data packets).
  uint16_t data_port = kDefaultDataPort;
  // Time window, seconds from the bag's first message (ReaderOptions::start_s, duration_s): only
  // the VelodyneScan messages received in it are delivered. Defaults: the whole bag.
  double start_s = 0;
  double duration_s = std::numeric_limits<double>::infinity();
};

struct BagPacketCounts {
  uint64_t scans = 0;         // VelodyneScan messages decoded
  uint64_t bad_messages = 0;  // messages of the topic that did not decode (also in malformed)
};

class BagPacketSource final : public PacketSource {
 public:
  // Opens `path` (open_bag, with the options' time window) and picks the topic. Throws BagError:
  // not a bag, no such topic, no LiDAR topic or several, or a topic whose type is not
  // velodyne_msgs/VelodyneScan.
  explicit BagPacketSource(const std::string& path, BagPacketSourceOptions options = {});
  // Over an opened reader (reading only `options.topic`'s messages, if it was opened so).
  BagPacketSource(std::unique_ptr<MessageReader> reader, BagPacketSourceOptions options,
                  const std::string& path);

  // Never waits: kPacket, or kEnd once the bag is read (or damage stopped it: error()).
  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override;
  // Messages outside the time window are the reader's (MessageReader::stats()).
  SourceStats stats() const override;
  std::string error() const override { return reader_->error(); }

  const std::string& topic() const { return options_.topic; }
  const BagPacketCounts& counts() const { return counts_; }
  const MessageReader& reader() const { return *reader_; }

 private:
  std::unique_ptr<MessageReader> reader_;
  BagPacketSourceOptions options_;
  std::vector<bool> is_topic_;  // per connection: the chosen topic
  std::vector<StampedPacket> packets_;
  size_t next_packet_ = 0;
  SourceStats stats_{};
  BagPacketCounts counts_;
};

}  // namespace lidartag::driver::bag
