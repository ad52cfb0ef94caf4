// A rosbag2 of VelodyneScan messages and the pcap of the same packets give the same rotations, bit
// for bit, through the same capture reader (model decision, decoder, batcher).
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <vector>

#include "bag/bag_files.hpp"
#include "lidartag/driver/bag/bag_packet_source.hpp"
#include "lidartag/driver/velodyne/io/capture_reader.hpp"

namespace lidartag::driver::bag {
namespace {

using testing::bag;
using testing::capture;

std::vector<Scan> rotations(velodyne::CaptureReader& reader) {
  std::vector<Scan> out;
  while (const Scan* s = reader.next()) out.push_back(*s);
  return out;
}

// Every cell of every ring and return that the rotation filled, compared as bytes (NaN included).
template <class T>
bool same_cells(const Scan& a, const Scan& b, const CellArray<T> Scan::*field) {
  const auto n = static_cast<size_t>(a.columns);
  for (int ret = 0; ret < a.returns; ++ret) {
    for (int ring = 0; ring < a.rings; ++ring) {
      const size_t ca = a.at(ret, ring, 0), cb = b.at(ret, ring, 0);
      if (std::memcmp((a.*field).data() + ca, (b.*field).data() + cb, n * sizeof(T)) != 0)
        return false;
    }
  }
  return true;
}

template <class T>
bool same_columns(const Scan& a, const Scan& b, const std::vector<T> Scan::*field) {
  return std::memcmp((a.*field).data(), (b.*field).data(),
                     static_cast<size_t>(a.columns) * sizeof(T)) == 0;
}

void expect_same_rotations(const std::string& bag_path, const std::string& pcap_path) {
  velodyne::CaptureReaderOptions options;
  velodyne::CaptureReader from_pcap(pcap_path, options);
  auto source = std::make_unique<BagPacketSource>(bag_path);
  const BagPacketSource* bag_source = source.get();
  velodyne::CaptureReader from_bag(std::move(source), options);
  const std::vector<Scan> p = rotations(from_pcap), b = rotations(from_bag);
  ASSERT_GT(p.size(), 1u);
  ASSERT_EQ(b.size(), p.size());
  EXPECT_EQ(from_bag.counts().decoded, from_pcap.counts().decoded);
  EXPECT_EQ(from_bag.counts().data_packets, from_pcap.counts().data_packets);
  EXPECT_EQ(from_bag.model(), from_pcap.model());
  EXPECT_EQ(from_bag.return_mode(), from_pcap.return_mode());
  EXPECT_EQ(bag_source->stats().malformed, 0u);
  EXPECT_EQ(bag_source->error(), "");
  size_t points = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    SCOPED_TRACE("rotation " + std::to_string(i));
    const Scan &a = p[i], &c = b[i];
    ASSERT_EQ(c.rings, a.rings);
    ASSERT_EQ(c.returns, a.returns);
    ASSERT_EQ(c.columns, a.columns);
    EXPECT_EQ(c.sequence, a.sequence);
    EXPECT_EQ(c.stamp_ns, a.stamp_ns);
    EXPECT_EQ(c.model, a.model);
    EXPECT_EQ(c.return_mode, a.return_mode);
    EXPECT_EQ(c.complete, a.complete);
    EXPECT_EQ(c.starts_at_cut, a.starts_at_cut);
    EXPECT_EQ(c.ends_at_cut, a.ends_at_cut);
    EXPECT_EQ(c.packets, a.packets);
    EXPECT_EQ(c.missing_packets, a.missing_packets);
    EXPECT_EQ(c.azimuth_jumps, a.azimuth_jumps);
    EXPECT_EQ(c.rpm, a.rpm);
    EXPECT_EQ(c.laser_id, a.laser_id);
    EXPECT_EQ(c.point_count(), a.point_count());
    EXPECT_TRUE(same_cells(a, c, &Scan::x));
    EXPECT_TRUE(same_cells(a, c, &Scan::y));
    EXPECT_TRUE(same_cells(a, c, &Scan::z));
    EXPECT_TRUE(same_cells(a, c, &Scan::range));
    EXPECT_TRUE(same_cells(a, c, &Scan::azimuth_deg));
    EXPECT_TRUE(same_cells(a, c, &Scan::time_s));
    EXPECT_TRUE(same_cells(a, c, &Scan::intensity));
    EXPECT_TRUE(same_cells(a, c, &Scan::return_type));
    EXPECT_TRUE(same_columns(a, c, &Scan::column_azimuth_deg));
    EXPECT_TRUE(same_columns(a, c, &Scan::column_time_s));
    points += a.point_count();
  }
  EXPECT_GT(points, 0u);
  const auto sa = from_pcap.batcher_stats(), sb = from_bag.batcher_stats();
  EXPECT_EQ(sb.rotations, sa.rotations);
  EXPECT_EQ(sb.complete, sa.complete);
  EXPECT_EQ(sb.missing_packets, sa.missing_packets);
}

TEST(BagVelodyne, Vlp16DualBagGivesThePcapsRotations) {
  LIDARTAG_REQUIRE_BAGS();
  expect_same_rotations(bag("rosbag2/vlp16_dual"), capture("vlp16_dual_nebula.pcap"));
}

TEST(BagVelodyne, Vlp32cBagGivesThePcapsRotations) {
  LIDARTAG_REQUIRE_BAGS();
  expect_same_rotations(bag("rosbag2/vlp32c"), capture("vlp32c_nebula_fov.pcap"));
}

TEST(BagVelodyne, Vls128BagGivesThePcapsRotations) {
  LIDARTAG_REQUIRE_BAGS();
  expect_same_rotations(bag("rosbag2/vls128"), capture("vls128_nebula.pcap"));
}

TEST(BagVelodyne, PacketCountsPerMessageAsRecorded) {
  LIDARTAG_REQUIRE_BAGS();
  // The README's packets per message, one VelodyneScan at a time.
  const std::vector<std::pair<std::string, std::vector<size_t>>> cases = {
      {"rosbag2/vlp16_dual", {151, 151, 151, 150}}};
  for (const auto& [name, want] : cases) {
    const auto reader = open_bag(bag(name));
    std::vector<size_t> got;
    std::vector<StampedPacket> packets;
    BagMessage m;
    while (reader->next(m)) {
      int64_t stamp = 0;
      ASSERT_EQ(decode_velodyne_scan(m.data, reader->connections()[m.connection].encoding, stamp,
                                     packets),
                DecodeResult::kOk);
      got.push_back(packets.size());
      for (const StampedPacket& p : packets) EXPECT_EQ(p.payload.size(), kVelodynePacketBytes);
    }
    EXPECT_EQ(got, want) << name;
  }
}

TEST(BagVelodyne, TopicOfAnotherTypeIsRefused) {
  LIDARTAG_REQUIRE_BAGS();
  try {
    BagPacketSource source(bag("ros1/luminar_pointcloud2_lz4.bag"));
    ADD_FAILURE() << "a PointCloud2 topic taken as packets";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find("not velodyne_msgs/VelodyneScan"), std::string::npos)
        << e.what();
  }
  BagPacketSourceOptions options;
  options.topic = "/nope";
  EXPECT_THROW(BagPacketSource(bag("rosbag2/vlp32c"), options), BagError);
  EXPECT_THROW(BagPacketSource(bag("mcap/talker.mcap")), BagError);  // no LiDAR topic
}

// A reader of hand-made CDR VelodyneScan messages on one topic.
class FakeReader final : public MessageReader {
 public:
  explicit FakeReader(std::vector<std::vector<uint8_t>> messages) : messages_(std::move(messages)) {
    connections_.push_back(
        {"/v", "velodyne_msgs/msg/VelodyneScan", Encoding::kCdr, messages_.size()});
  }
  bool next(BagMessage& out) override {
    if (next_ >= messages_.size()) return false;
    out.connection = 0;
    out.time_ns = 1;
    out.data = messages_[next_++];
    return true;
  }
  BagFormat format() const override { return BagFormat::kMcap; }

 private:
  std::vector<std::vector<uint8_t>> messages_;
  size_t next_ = 0;
};

// A CDR VelodyneScan whose packets have these stamps (seconds) and payloads filled with their
// index.
std::vector<uint8_t> velodyne_scan(const std::vector<int32_t>& stamps_s) {
  std::vector<uint8_t> b = {0, 1, 0, 0};
  auto put = [&b](auto v) {
    while ((b.size() - 4) % sizeof(v) != 0) b.push_back(0);
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    b.insert(b.end(), p, p + sizeof(v));
  };
  put(int32_t{7});
  put(uint32_t{0});
  put(uint32_t{2});
  b.insert(b.end(), {'v', 0});
  put(static_cast<uint32_t>(stamps_s.size()));
  for (size_t i = 0; i < stamps_s.size(); ++i) {
    put(stamps_s[i]);
    put(uint32_t{500});
    b.insert(b.end(), kVelodynePacketBytes, static_cast<uint8_t>(i + 1));
  }
  return b;
}

TEST(BagVelodyne, PacketSourceCountsCorruptStampsAndTruncatedMessages) {
  std::vector<uint8_t> cut = velodyne_scan({3, 4});
  cut.resize(cut.size() - 100);  // the second packet cut short
  auto reader = std::make_unique<FakeReader>(
      std::vector<std::vector<uint8_t>>{velodyne_scan({1, -5, 2}), cut});
  BagPacketSource source(std::move(reader), {}, "fake");
  EXPECT_EQ(source.topic(), "/v");
  std::vector<int64_t> stamps;
  std::vector<uint8_t> first_bytes;
  RawPacket p;
  while (source.next(p, std::chrono::milliseconds(0)) == ReadStatus::kPacket) {
    ASSERT_EQ(p.payload.size(), kVelodynePacketBytes);
    EXPECT_EQ(p.destination_port, kDefaultDataPort);
    stamps.push_back(p.receive_time_ns);
    first_bytes.push_back(p.payload[0]);
  }
  // The negative stamp is dropped; the whole packet before the cut is kept.
  EXPECT_EQ(stamps, (std::vector<int64_t>{1'000'000'500, 2'000'000'500, 3'000'000'500}));
  EXPECT_EQ(first_bytes, (std::vector<uint8_t>{1, 3, 1}));
  EXPECT_EQ(source.stats().packets, 3u);
  EXPECT_EQ(source.stats().malformed, 2u);  // the stamp, the cut message
  EXPECT_EQ(source.stats().truncated, 1u);
  EXPECT_EQ(source.counts().scans, 2u);
  EXPECT_EQ(source.counts().bad_messages, 1u);
}

}  // namespace
}  // namespace lidartag::driver::bag
