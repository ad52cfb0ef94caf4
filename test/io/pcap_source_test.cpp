#include "lidartag/driver/io/pcap_source.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <vector>

#include "io/pcap_builder.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"

namespace lidartag::velodyne {
namespace {

using test::Bytes;
using test::Record;
using namespace std::chrono_literals;

constexpr uint32_t kLinktypeEthernet = 1, kLinktypeRaw = 101, kLinktypeSll = 113,
                   kLinktypeIpv4 = 228, kLinktypeSll2 = 276;
constexpr int64_t kT0 = 1'600'000'000'000'000'000;  // a capture time, ns since epoch

class TempFile {
 public:
  explicit TempFile(const std::string& name)
      : path_((std::filesystem::temp_directory_path() /
               ("lidartag_pcap_source_" + std::to_string(::getpid()) + "_" + name))
                  .string()) {}
  ~TempFile() { std::filesystem::remove(path_); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

struct Received {
  Bytes payload;
  int64_t time_ns;
  uint16_t port;
  uint32_t source;
};

std::vector<Received> read_all(driver::PcapSource& source, size_t limit = 1000) {
  std::vector<Received> out;
  driver::RawPacket p;
  while (out.size() < limit && source.next(p, 0ms) == driver::ReadStatus::kPacket) {
    out.push_back({Bytes(p.payload.begin(), p.payload.end()), p.receive_time_ns, p.destination_port,
                   p.source_ipv4});
  }
  return out;
}

std::vector<Received> read_file(const std::string& name, const Bytes& file,
                                driver::SourceStats* stats = nullptr,
                                driver::PcapSourceOptions options = {}) {
  TempFile tmp(name);
  test::write_file(tmp.path(), file);
  driver::PcapSource source(tmp.path(), options);
  auto packets = read_all(source);
  if (stats) *stats = source.stats();
  return packets;
}

TEST(PcapSource, ReadsWhatPcapWriterWrote) {
  TempFile tmp("writer.pcap");
  const Bytes data = test::payload_bytes(1206, 1), position = test::payload_bytes(512, 2);
  {
    driver::PcapWriter writer(tmp.path());
    writer.write_udp(data, kT0 + 1'234'000, 2368);
    writer.write_udp(position, kT0 + 2'000'000, 8308, 0x0A000001);
    writer.close();
  }
  driver::PcapSource source(tmp.path());
  EXPECT_EQ(source.link_type(), kLinktypeEthernet);
  const auto packets = read_all(source);
  ASSERT_EQ(packets.size(), 2u);
  EXPECT_EQ(packets[0].payload, data);
  EXPECT_EQ(packets[0].time_ns, kT0 + 1'234'000);
  EXPECT_EQ(packets[0].port, 2368);
  EXPECT_EQ(packets[0].source, 0xC0A801C9u);
  EXPECT_EQ(packets[1].payload, position);
  EXPECT_EQ(packets[1].port, 8308);
  EXPECT_EQ(packets[1].source, 0x0A000001u);
  const driver::SourceStats stats = source.stats();
  EXPECT_EQ(stats.packets, 2u);
  EXPECT_EQ(stats.bytes, 1206u + 512u);
  EXPECT_EQ(stats.ignored + stats.truncated + stats.malformed, 0u);
  driver::RawPacket p;
  EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kEnd);
  EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kEnd);  // stays at the end
}

TEST(PcapSource, EveryLinkTypeDeliversThePayload) {
  const Bytes payload = test::payload_bytes(1206, 7);
  const Bytes ip = test::ipv4_udp(payload, 2368);
  struct Case {
    const char* name;
    uint32_t linktype;
    Bytes frame;
  };
  const std::vector<Case> cases = {
      {"ethernet", kLinktypeEthernet, test::ethernet(ip)},
      {"vlan", kLinktypeEthernet, test::ethernet(ip, 0x0800, {0x8100})},
      {"qinq", kLinktypeEthernet, test::ethernet(ip, 0x0800, {0x88A8, 0x8100})},
      {"double-8100", kLinktypeEthernet, test::ethernet(ip, 0x0800, {0x8100, 0x8100})},
      {"sll", kLinktypeSll, test::linux_sll(ip)},
      {"sll2", kLinktypeSll2, test::linux_sll2(ip)},
      {"raw", kLinktypeRaw, ip},
      {"ipv4", kLinktypeIpv4, ip},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    driver::SourceStats stats;
    const auto packets = read_file(std::string(c.name) + ".pcap",
                                   test::classic_pcap(c.linktype, {{c.frame, kT0}}), &stats);
    ASSERT_EQ(packets.size(), 1u);
    EXPECT_EQ(packets[0].payload, payload);
    EXPECT_EQ(packets[0].port, 2368);
    EXPECT_EQ(packets[0].time_ns, kT0);
    EXPECT_EQ(stats.ignored + stats.truncated + stats.malformed, 0u);
  }
}

TEST(PcapSource, VlanTaggedCookedCapturesDeliverThePayload) {
  const Bytes payload = test::payload_bytes(512, 3);
  const Bytes ip = test::ipv4_udp(payload, 8308);
  Bytes tagged;  // TCI + inner EtherType after the cooked header
  test::put_be16(tagged, 0x0064);
  test::put_be16(tagged, 0x0800);
  test::append(tagged, ip);
  for (auto [name, file] :
       {std::pair{"sll-vlan",
                  test::classic_pcap(kLinktypeSll, {{test::linux_sll(tagged, 0x8100), kT0}})},
        std::pair{"sll2-vlan",
                  test::classic_pcap(kLinktypeSll2, {{test::linux_sll2(tagged, 0x8100), kT0}})}}) {
    SCOPED_TRACE(name);
    const auto packets = read_file(std::string(name) + ".pcap", file);
    ASSERT_EQ(packets.size(), 1u);
    EXPECT_EQ(packets[0].payload, payload);
    EXPECT_EQ(packets[0].port, 8308);
  }
}

TEST(PcapSource, Ipv4OptionsAreSkippedUsingIhl) {
  const Bytes payload = test::payload_bytes(1206, 9);
  for (size_t words : {1u, 3u, 10u}) {
    SCOPED_TRACE(words);
    test::Ipv4Options o;
    o.option_words = words;
    const auto packets =
        read_file("options.pcap",
                  test::classic_pcap(kLinktypeEthernet,
                                     {{test::ethernet(test::ipv4_udp(payload, 2368, o)), kT0}}));
    ASSERT_EQ(packets.size(), 1u);
    EXPECT_EQ(packets[0].payload, payload);
  }
}

TEST(PcapSource, OtherTrafficIsIgnoredAndCounted) {
  const Bytes payload = test::payload_bytes(1206, 1);
  test::Ipv4Options tcp;
  tcp.protocol = 6;
  test::Ipv4Options other_sender;
  other_sender.src = 0x0A0000FE;
  test::Ipv4Options first_fragment;
  first_fragment.flags_fragment = 0x2000;  // more fragments
  test::Ipv4Options later_fragment;
  later_fragment.flags_fragment = 0x00B9;  // offset 185 * 8
  const Bytes arp(28, 0x01), ipv6(60, 0x60);
  std::vector<Record> records = {
      {test::ethernet(test::ipv4_udp(payload, 2368)), kT0},           // delivered
      {test::ethernet(arp, 0x0806), kT0 + 1},                         // ARP
      {test::ethernet(ipv6, 0x86DD), kT0 + 2},                        // IPv6
      {test::ethernet(test::ipv4_udp(payload, 2368, tcp)), kT0 + 3},  // TCP
      {test::ethernet(test::ipv4_udp(payload, 53)), kT0 + 4},         // DNS port
      {test::ethernet(test::ipv4_udp(payload, 2368, first_fragment)), kT0 + 5},
      {test::ethernet(test::ipv4_udp(payload, 2368, later_fragment)), kT0 + 6},
      {test::ethernet(test::ipv4_udp(payload, 2368, other_sender)), kT0 + 7},
      {test::ethernet(test::ipv4_udp(payload, 8308)), kT0 + 8},  // delivered
  };
  const Bytes file = test::classic_pcap(kLinktypeEthernet, records);
  {
    TempFile tmp("other.pcap");
    test::write_file(tmp.path(), file);
    driver::PcapSource source(tmp.path());
    const auto packets = read_all(source);
    ASSERT_EQ(packets.size(), 3u);  // the other sender passes without a sensor filter
    EXPECT_EQ(source.stats().ignored, 6u);
    EXPECT_EQ(source.fragments(), 2u);
    EXPECT_EQ(source.records(), records.size());
  }
  driver::PcapSourceOptions only_sensor;
  only_sensor.sensor_ipv4 = 0xC0A801C9;
  driver::SourceStats stats;
  const auto packets = read_file("other2.pcap", file, &stats, only_sensor);
  ASSERT_EQ(packets.size(), 2u);
  EXPECT_EQ(packets[0].port, 2368);
  EXPECT_EQ(packets[1].port, 8308);
  EXPECT_EQ(stats.ignored, 6u);         // as without the filter
  EXPECT_EQ(stats.foreign_source, 1u);  // the other sender's packet to the data port
}

TEST(PcapSource, ConfiguredPortsSelectTheTraffic) {
  const Bytes payload = test::payload_bytes(100, 1);
  driver::PcapSourceOptions options;
  options.data_port = 2369;
  options.position_port = 8309;
  driver::SourceStats stats;
  const auto packets =
      read_file("ports.pcap",
                test::classic_pcap(kLinktypeEthernet,
                                   {{test::ethernet(test::ipv4_udp(payload, 2368)), kT0},
                                    {test::ethernet(test::ipv4_udp(payload, 2369)), kT0 + 1},
                                    {test::ethernet(test::ipv4_udp(payload, 8309)), kT0 + 2}}),
                &stats, options);
  ASSERT_EQ(packets.size(), 2u);
  EXPECT_EQ(packets[0].port, 2369);
  EXPECT_EQ(packets[1].port, 8309);
  EXPECT_EQ(stats.ignored, 1u);
}

TEST(PcapSource, RecordCutBySnapLengthIsCountedNotReadPast) {
  const Bytes payload = test::payload_bytes(1206, 4);
  Record cut{test::ethernet(test::ipv4_udp(payload, 2368)), kT0, 200};  // 200 bytes missing
  Record header_cut{test::ethernet(test::ipv4_udp(payload, 2368)), kT0 + 1000,
                    1206 + 8 + 10};  // inside the IPv4 header
  Record good{test::ethernet(test::ipv4_udp(payload, 2368)), kT0 + 2000};
  driver::SourceStats stats;
  const auto packets =
      read_file("cut.pcap", test::classic_pcap(kLinktypeEthernet, {cut, header_cut, good}), &stats);
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(packets[0].payload, payload);
  EXPECT_EQ(packets[0].time_ns, kT0 + 2000);
  EXPECT_EQ(stats.truncated, 2u);
}

TEST(PcapSource, EthernetPaddingPastTheIpLengthIsIgnored) {
  const Bytes payload = test::payload_bytes(10, 4);  // a 52-byte frame, padded to 60 on the wire
  Bytes frame = test::ethernet(test::ipv4_udp(payload, 2368));
  frame.resize(60, 0xAA);
  const auto packets = read_file("pad.pcap", test::classic_pcap(kLinktypeEthernet, {{frame, kT0}}));
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(packets[0].payload, payload);
}

TEST(PcapSource, FileTruncatedMidRecordEndsAfterTheWholeRecords) {
  const Bytes payload = test::payload_bytes(1206, 5);
  Bytes file = test::classic_pcap(kLinktypeEthernet,
                                  {{test::ethernet(test::ipv4_udp(payload, 2368)), kT0},
                                   {test::ethernet(test::ipv4_udp(payload, 2368)), kT0 + 1000}});
  file.resize(file.size() - 500);
  TempFile tmp("short.pcap");
  test::write_file(tmp.path(), file);
  driver::PcapSource source(tmp.path());
  const auto packets = read_all(source);
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(packets[0].payload, payload);
  EXPECT_EQ(source.stats().truncated, 1u);
  EXPECT_NE(source.last_error().find("truncated"), std::string::npos) << source.last_error();
  driver::RawPacket p;
  EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kEnd);
}

TEST(PcapSource, CorruptHeadersAreCountedAsMalformed) {
  const Bytes payload = test::payload_bytes(1206, 6);
  test::Ipv4Options short_ihl;
  short_ihl.version_ihl_override = 0x43;
  test::Ipv4Options not_v4;
  not_v4.version_ihl_override = 0x55;
  test::Ipv4Options udp_too_long;
  udp_too_long.udp_length_delta = 40;
  test::Ipv4Options total_too_short;
  total_too_short.total_length_delta = -1220;
  driver::SourceStats stats;
  const auto packets = read_file(
      "bad.pcap",
      test::classic_pcap(kLinktypeEthernet,
                         {{test::ethernet(test::ipv4_udp(payload, 2368, short_ihl)), kT0},
                          {test::ethernet(test::ipv4_udp(payload, 2368, not_v4)), kT0 + 1},
                          {test::ethernet(test::ipv4_udp(payload, 2368, udp_too_long)), kT0 + 2},
                          {test::ethernet(test::ipv4_udp(payload, 2368, total_too_short)), kT0 + 3},
                          {test::ethernet(test::ipv4_udp(payload, 2368)), kT0 + 4}}),
      &stats);
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(stats.malformed, 4u);
}

TEST(PcapSource, UdpLengthLongerThanTheCaptureIsTruncated) {
  // The IPv4 and UDP lengths agree but the frame holds fewer bytes than both claim.
  const Bytes payload = test::payload_bytes(1206, 6);
  test::Ipv4Options longer;
  longer.udp_length_delta = 100;
  longer.total_length_delta = 100;
  driver::SourceStats stats;
  const auto packets =
      read_file("udplong.pcap",
                test::classic_pcap(kLinktypeEthernet,
                                   {{test::ethernet(test::ipv4_udp(payload, 2368, longer)), kT0}}),
                &stats);
  EXPECT_TRUE(packets.empty());
  EXPECT_EQ(stats.truncated, 1u);
}

TEST(PcapSource, ReadsNanosecondPcap) {
  const Bytes payload = test::payload_bytes(512, 8);
  const auto packets = read_file(
      "nano.pcap", test::classic_pcap(
                       kLinktypeEthernet,
                       {{test::ethernet(test::ipv4_udp(payload, 8308)), kT0 + 123'456'789}}, true));
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(packets[0].time_ns, kT0 + 123'456'789);
}

TEST(PcapSource, ReadsPcapng) {
  const Bytes data = test::payload_bytes(1206, 10), position = test::payload_bytes(512, 11);
  const std::vector<Record> records = {
      {test::ethernet(test::ipv4_udp(data, 2368)), kT0 + 1'000'000},
      {test::ethernet(test::ipv4_udp(position, 8308)), kT0 + 2'500'000}};
  {
    SCOPED_TRACE("microseconds");
    const auto packets = read_file("us.pcapng", test::pcapng(1, records));
    ASSERT_EQ(packets.size(), 2u);
    EXPECT_EQ(packets[0].payload, data);
    EXPECT_EQ(packets[0].time_ns, kT0 + 1'000'000);
    EXPECT_EQ(packets[1].payload, position);
    EXPECT_EQ(packets[1].port, 8308);
    EXPECT_EQ(packets[1].time_ns, kT0 + 2'500'000);
  }
  {
    SCOPED_TRACE("nanoseconds, cooked v2");
    std::vector<Record> ns = {{test::linux_sll2(test::ipv4_udp(data, 2368)), kT0 + 777}};
    const auto packets = read_file("ns.pcapng", test::pcapng(276, ns, 9));
    ASSERT_EQ(packets.size(), 1u);
    EXPECT_EQ(packets[0].time_ns, kT0 + 777);
    EXPECT_EQ(packets[0].payload, data);
  }
}

TEST(PcapSource, ImpossibleTimestampsAreCountedAsMalformedAndSkipped) {
  // pcapng timestamps are 64-bit ticks: a corrupt one is 2^64 us, beyond any int64 of ns.
  const Bytes payload = test::payload_bytes(1206, 10);
  const Bytes frame = test::ethernet(test::ipv4_udp(payload, 2368));
  Bytes file = test::pcapng(1, {{frame, kT0}, {frame, kT0 + 1000}, {frame, kT0 + 2000}});
  // Section header 28 bytes, interface 20; the first packet block's timestamp (high word) at
  // 12 bytes into it, the second block 1280 bytes further.
  const size_t first_epb = 28 + 20;
  ASSERT_EQ(file[first_epb], 6);
  for (size_t i = 0; i < 4; ++i) file[first_epb + 12 + i] = 0xFF;
  const size_t second_epb = first_epb + 32 + ((frame.size() + 3) / 4) * 4;
  ASSERT_EQ(file[second_epb], 6);
  file[second_epb + 12 + 3] = 0x80;  // 2^63 us
  TempFile tmp("times.pcapng");
  test::write_file(tmp.path(), file);
  driver::PcapSource source(tmp.path());
  const auto packets = read_all(source);
  ASSERT_EQ(packets.size(), 1u);
  EXPECT_EQ(packets[0].time_ns, kT0 + 2000);
  EXPECT_EQ(source.stats().malformed, 2u);
  EXPECT_NE(source.last_error().find("impossible timestamp"), std::string::npos)
      << source.last_error();

  // A classic record whose microseconds are not below a second is corrupt too.
  Bytes classic = test::classic_pcap(kLinktypeEthernet, {{frame, kT0}, {frame, kT0 + 1000}});
  classic[24 + 4 + 3] = 0xFF;  // ts_usec of the first record >= 2^24 * 255
  driver::SourceStats stats;
  const auto kept = read_file("usec.pcap", classic, &stats);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].time_ns, kT0 + 1000);
  EXPECT_EQ(stats.malformed, 1u);
}

TEST(PcapSource, ZeroLengthAndHugeLengthRecordsAreCounted) {
  const Bytes payload = test::payload_bytes(1206, 13);
  const Bytes frame = test::ethernet(test::ipv4_udp(payload, 2368));
  // A record with no data at all, between two good ones.
  Bytes file =
      test::classic_pcap(kLinktypeEthernet, {{frame, kT0}, {{}, kT0 + 1}, {frame, kT0 + 2}});
  driver::SourceStats stats;
  auto packets = read_file("zero.pcap", file, &stats);
  EXPECT_EQ(packets.size(), 2u);
  EXPECT_EQ(stats.truncated, 1u);
  // A record claiming 4 GB: libpcap refuses it, the pass ends there, counted.
  file = test::classic_pcap(kLinktypeEthernet, {{frame, kT0}, {frame, kT0 + 1}});
  const size_t second = 24 + 16 + frame.size();
  for (size_t i = 0; i < 4; ++i) file[second + 8 + i] = 0xFF;
  packets = read_file("huge.pcap", file, &stats);
  EXPECT_EQ(packets.size(), 1u);
  EXPECT_EQ(stats.malformed + stats.truncated, 1u);
}

TEST(PcapSource, ClassicRecordsFrom2038OnKeepTheirTime) {
  // Classic pcap's seconds are unsigned 32-bit (good to 2106); libpcap hands them over signed,
  // and a capture dated 2039 once replayed nothing (every record "impossible").
  const Bytes frame = test::ethernet(test::ipv4_udp(test::payload_bytes(1206, 3), 2368));
  const int64_t y2038 = 2'147'483'648LL * 1'000'000'000;  // 2038-01-19T03:14:08Z
  const int64_t y2039 = 2'177'452'800LL * 1'000'000'000;  // 2039-01-01
  for (const bool nano : {false, true}) {
    SCOPED_TRACE(nano ? "nanoseconds" : "microseconds");
    driver::SourceStats stats;
    const auto packets = read_file(
        "y2038.pcap",
        test::classic_pcap(kLinktypeEthernet,
                           {{frame, y2038 - 1'000'000'000}, {frame, y2038}, {frame, y2039 + 5000}},
                           nano),
        &stats);
    ASSERT_EQ(packets.size(), 3u);
    EXPECT_EQ(packets[0].time_ns, y2038 - 1'000'000'000);
    EXPECT_EQ(packets[1].time_ns, y2038);
    EXPECT_EQ(packets[2].time_ns, y2039 + 5000);
    EXPECT_EQ(stats.malformed, 0u);
  }
}

TEST(PcapSource, ARecordThatStopsTheReplayBeforeTheEndIsAnError) {
  // A corrupt record length in the middle (libpcap cannot read on): the replay must not end
  // looking whole. The source names the record and the bytes left unread.
  const Bytes frame = test::ethernet(test::ipv4_udp(test::payload_bytes(1206, 4), 2368));
  std::vector<Record> records;
  for (int i = 0; i < 10; ++i) records.push_back({frame, kT0 + i * 1000});
  Bytes file = test::classic_pcap(kLinktypeEthernet, records);
  const size_t fourth = 24 + 3 * (16 + frame.size());
  for (size_t i = 0; i < 4; ++i) file[fourth + 8 + i] = i == 2 ? 0x10 : 0x00;  // caplen 1 MiB
  TempFile tmp("cut.pcap");
  test::write_file(tmp.path(), file);
  driver::PcapSource source(tmp.path());
  EXPECT_EQ(read_all(source).size(), 3u);
  EXPECT_NE(source.error().find("unreadable after record 3"), std::string::npos) << source.error();
  EXPECT_NE(source.error().find("bytes not read"), std::string::npos) << source.error();
  // A file that ends inside its last record (a recording stopped mid-write) was read whole.
  Bytes cut = test::classic_pcap(kLinktypeEthernet, records);
  cut.resize(cut.size() - 500);
  TempFile tmp2("end.pcap");
  test::write_file(tmp2.path(), cut);
  driver::PcapSource ends(tmp2.path());
  EXPECT_EQ(read_all(ends).size(), 9u);
  EXPECT_EQ(ends.stats().truncated, 1u);
  EXPECT_EQ(ends.error(), "");
}

TEST(PcapSource, LoopRestartsWithMonotonicTime) {
  const Bytes payload = test::payload_bytes(1206, 12);
  const Bytes frame = test::ethernet(test::ipv4_udp(payload, 2368));
  driver::PcapSourceOptions options;
  options.loop = true;
  TempFile tmp("loop.pcap");
  test::write_file(tmp.path(), test::classic_pcap(kLinktypeEthernet, {{frame, kT0},
                                                                      {frame, kT0 + 1'000'000},
                                                                      {frame, kT0 + 3'000'000}}));
  driver::PcapSource source(tmp.path(), options);
  const auto packets = read_all(source, 7);
  ASSERT_EQ(packets.size(), 7u);
  // Pass 2 starts one last-interval (2 ms) after the end of pass 1 (3 ms): shift 5 ms.
  const std::vector<int64_t> expected = {0,         1'000'000, 3'000'000, 5'000'000,
                                         6'000'000, 8'000'000, 10'000'000};
  for (size_t i = 0; i < packets.size(); ++i) EXPECT_EQ(packets[i].time_ns - kT0, expected[i]);
  EXPECT_EQ(source.passes(), 2u);
  EXPECT_EQ(source.stats().packets, 7u);
}

TEST(PcapSource, LoopOverAFileWithoutUsablePacketsEnds) {
  driver::PcapSourceOptions options;
  options.loop = true;
  const Bytes frame = test::ethernet(test::ipv4_udp(test::payload_bytes(10, 1), 53));
  driver::SourceStats stats;
  const auto packets = read_file(
      "loop-empty.pcap", test::classic_pcap(kLinktypeEthernet, {{frame, kT0}}), &stats, options);
  EXPECT_TRUE(packets.empty());
  EXPECT_EQ(stats.ignored, 1u);
}

TEST(ReplaySchedule, DueTimesFollowCaptureTimeScaledByRate) {
  using Clock = driver::ReplaySchedule::Clock;
  const Clock::time_point start{std::chrono::seconds(100)};
  driver::ReplaySchedule realtime(1.0);
  EXPECT_EQ(realtime.due(kT0, start), start);
  EXPECT_EQ(realtime.due(kT0 + 1'000'000, start + 5s), start + 1ms);  // anchored at the first
  EXPECT_EQ(realtime.due(kT0 + 2'000'000'000, start), start + 2s);
  driver::ReplaySchedule fast(4.0);
  EXPECT_EQ(fast.due(kT0, start), start);
  EXPECT_EQ(fast.due(kT0 + 2'000'000'000, start), start + 500ms);
  driver::ReplaySchedule slow(0.5);
  EXPECT_EQ(slow.due(kT0, start), start);
  EXPECT_EQ(slow.due(kT0 + 1'000'000, start), start + 2ms);
  slow.reset();
  EXPECT_EQ(slow.due(kT0 + 1'000'000, start + 1s), start + 1s);
}

TEST(PcapSource, PacedReplayWaitsForCaptureTimeAndTimesOut) {
  const Bytes frame = test::ethernet(test::ipv4_udp(test::payload_bytes(1206, 1), 2368));
  TempFile tmp("paced.pcap");
  // Packets 20 s apart: at real time the second is never due within a short timeout.
  test::write_file(tmp.path(), test::classic_pcap(kLinktypeEthernet,
                                                  {{frame, kT0}, {frame, kT0 + 20'000'000'000}}));
  driver::PcapSourceOptions options;
  options.pacing = driver::ReplayPacing::kCaptureTime;
  {
    driver::PcapSource source(tmp.path(), options);
    driver::RawPacket p;
    EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kPacket);
    EXPECT_EQ(source.next(p, 1ms), driver::ReadStatus::kTimeout);
    EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kTimeout);  // still pending, not skipped
    EXPECT_EQ(source.stats().packets, 1u);
  }
  // At 1000x the 20 s gap takes 20 ms: delivered within a generous timeout, not before ~20 ms.
  options.rate = 1000.0;
  driver::PcapSource source(tmp.path(), options);
  driver::RawPacket p;
  ASSERT_EQ(source.next(p, 0ms), driver::ReadStatus::kPacket);
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(source.next(p, 10s), driver::ReadStatus::kPacket);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 15ms);
  EXPECT_EQ(p.receive_time_ns, kT0 + 20'000'000'000);  // times are capture times, not wall time
}

TEST(PcapSource, OpeningErrorsNameTheFile) {
  const std::string missing = "/nonexistent-lidartag/missing.pcap";
  try {
    driver::PcapSource source(missing);
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  TempFile garbage("garbage.pcap");
  test::write_file(garbage.path(), Bytes(100, 0x42));
  EXPECT_THROW(driver::PcapSource source(garbage.path()), driver::IoError);
  TempFile usb("usb.pcap");
  test::write_file(usb.path(), test::classic_pcap(189, {}));  // LINKTYPE_USB_LINUX
  try {
    driver::PcapSource source(usb.path());
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("link type"), std::string::npos) << e.what();
  }
  TempFile good("good.pcap");
  test::write_file(good.path(), test::classic_pcap(kLinktypeEthernet, {}));
  driver::PcapSourceOptions bad_rate;
  bad_rate.pacing = driver::ReplayPacing::kCaptureTime;
  bad_rate.rate = 0.0;
  EXPECT_THROW(driver::PcapSource source(good.path(), bad_rate), driver::IoError);
}

TEST(PcapSource, RealCaptureCountsDataAndPositionPackets) {
  const std::string path = LIDARTAG_SHARED_DIR "/captures/vlp16_mrpt_gps.pcap";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "capture not available: " << path;
  driver::PcapSource source(path);
  size_t data = 0, position = 0;
  int64_t last = 0;
  bool monotonic = true;
  driver::RawPacket p;
  while (source.next(p, 0ms) == driver::ReadStatus::kPacket) {
    if (p.destination_port == 2368 && p.payload.size() == 1206) ++data;
    if (p.destination_port == 8308 && p.payload.size() == 512) ++position;
    monotonic = monotonic && p.receive_time_ns >= last;
    last = p.receive_time_ns;
  }
  EXPECT_EQ(data, 293u);
  EXPECT_EQ(position, 57u);
  EXPECT_TRUE(monotonic);
  EXPECT_EQ(source.stats().truncated + source.stats().malformed, 0u);
}

}  // namespace
}  // namespace lidartag::velodyne
