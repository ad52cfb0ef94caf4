// Fuzz target: a ROS 1 bag, an MCAP file or a ROS 2 sqlite3 bag (.db3 named directly) through
// open_bag and MessageReader, and every message through the decoder its type calls for
// (VelodyneScan, PointCloud2 with cloud_columns, Ouster packets, strings), as `lidartag` and
// Python read them. One source, three targets (ros1_bag, mcap, rosbag2): each has its format's
// seed corpus; any input is read by content. The file lives in memory (fuzz_util.hpp's MemFile);
// sqlite opens it read-only through its /proc/self/fd path. Inputs whose size is a multiple of 3
// are read with a time window. Checks: a file refused at open is refused with BagError, in one
// line; otherwise the reader ends, every message names a known connection, the counters agree with
// what was delivered, no message is larger than the bound on a chunk, a windowed read delivers
// nothing before the bag's start, and the error text is one line.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/driver/bag/messages.hpp"

using namespace lidartag;
namespace bag = driver::bag;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static fuzz::MemFile file;
  const std::string& path = file.write({data, size});
  bag::ReaderOptions options;
  options.max_chunk_bytes = uint64_t{16} << 20;  // bounds what a corrupt size may make it hold
  const bool windowed = size % 3 == 0;
  if (windowed) {
    options.start_s = 0.05;
    options.duration_s = 0.1;
  }
  std::unique_ptr<bag::MessageReader> reader;
  try {
    reader = bag::open_bag(path, options);
  } catch (const bag::BagError& e) {
    fuzz::check(fuzz::one_line(e.what()), "an open error of several lines");
    return 0;
  }
  bag::BagMessage m;
  uint64_t delivered = 0, bytes = 0;
  std::vector<bag::StampedPacket> packets;
  bag::PointCloudView cloud;
  bag::CloudColumns columns;
  while (reader->next(m)) {
    ++delivered;
    bytes += m.data.size();
    const auto& connections = reader->connections();
    fuzz::check(m.connection < connections.size(), "a message of no connection");
    fuzz::check(m.data.size() <= options.max_chunk_bytes, "a message larger than the bound");
    if (windowed) {
      fuzz::check(reader->start_time_ns().has_value(), "a windowed read without a start");
      fuzz::check(m.time_ns >= *reader->start_time_ns(), "a message before the bag's start");
    }
    const bag::Connection& c = connections[m.connection];
    int64_t stamp = 0;
    switch (bag::message_kind(c.type)) {
      case bag::MessageKind::kVelodyneScan:
        (void)bag::decode_velodyne_scan(m.data, c.encoding, stamp, packets);
        for (const auto& p : packets)
          fuzz::check(p.payload.size() == bag::kVelodynePacketBytes, "a packet of another size");
        break;
      case bag::MessageKind::kPointCloud2:
        if (bag::decode_point_cloud(m.data, c.encoding, cloud) == bag::DecodeResult::kOk) {
          bag::cloud_columns(cloud, columns);
          for (const auto& column : columns.columns)
            fuzz::check(column.size() == columns.width * columns.height,
                        "a cloud column of the wrong length");
          // A cloud with a field has a point step of a byte or more.
          fuzz::check(columns.columns.empty() || columns.width * columns.height <= m.data.size(),
                      "more points than bytes");
        }
        break;
      case bag::MessageKind::kOusterPacket: {
        std::span<const uint8_t> packet;
        (void)bag::decode_ouster_packet(m.data, c.encoding, packet);
        break;
      }
      case bag::MessageKind::kString: {
        std::string_view text;
        (void)bag::decode_string(m.data, c.encoding, text);
        break;
      }
      case bag::MessageKind::kOther:
        break;
    }
  }
  fuzz::check(!reader->next(m), "a reader that ended and went on");
  const bag::ReadStats& s = reader->stats();
  fuzz::check(s.messages == delivered, "messages delivered and counted differ");
  fuzz::check(s.bytes == bytes, "bytes delivered and counted differ");
  fuzz::check(s.skipped_chunks <= s.chunks || reader->format() == bag::BagFormat::kRosbag2,
              "more chunks skipped than read");
  fuzz::check(fuzz::one_line(reader->error()), "an error text of several lines");
  return 0;
}
