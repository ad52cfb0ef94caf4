#include "lidartag/driver/io/udp_source.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <vector>

#include "daemon/namespaces.hpp"
#include "temp_dir.hpp"

namespace lidartag::velodyne {
namespace {

using namespace std::chrono_literals;

// A plain sender on loopback: the test's own packets, bounded in number.
class Sender {
 public:
  Sender() : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {}
  ~Sender() { ::close(fd_); }
  bool send(uint16_t port, const std::vector<uint8_t>& payload) const {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return ::sendto(fd_, payload.data(), payload.size(), 0, reinterpret_cast<sockaddr*>(&to),
                    sizeof(to)) == static_cast<ssize_t>(payload.size());
  }

 private:
  int fd_;
};

driver::UdpSourceOptions loopback_options() {
  driver::UdpSourceOptions o;
  o.bind_address = "127.0.0.1";
  o.data_port = 0;  // kernel-chosen free ports
  o.position_port = 0;
  return o;
}

std::vector<uint8_t> payload(size_t n, uint8_t seed) {
  std::vector<uint8_t> p(n);
  for (size_t i = 0; i < n; ++i) p[i] = static_cast<uint8_t>(seed + 3 * i);
  return p;
}

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

TEST(UdpSource, ReceivesDataAndPositionPacketsWithPortsAndKernelTimes) {
  driver::UdpSource source(loopback_options());
  ASSERT_NE(source.data_port(), 0);
  ASSERT_NE(source.position_port(), 0);
  ASSERT_NE(source.data_port(), source.position_port());
  EXPECT_TRUE(source.kernel_timestamps_active());
  EXPECT_GT(source.granted_receive_buffer(), 0);

  Sender sender;
  const auto data = payload(1206, 1), position = payload(512, 2);
  const int64_t before = now_ns();
  ASSERT_TRUE(sender.send(source.data_port(), data));
  ASSERT_TRUE(sender.send(source.position_port(), position));

  std::vector<std::pair<std::vector<uint8_t>, uint16_t>> got;
  driver::RawPacket p;
  for (int i = 0; i < 2; ++i) {
    ASSERT_EQ(source.next(p, 1000ms), driver::ReadStatus::kPacket);
    got.emplace_back(std::vector<uint8_t>(p.payload.begin(), p.payload.end()), p.destination_port);
    // The kernel stamps on arrival: after the send began, before recvmsg returned it.
    EXPECT_GE(p.receive_time_ns, before);
    EXPECT_LE(p.receive_time_ns, now_ns());
    EXPECT_EQ(p.source_ipv4, 0x7F000001u);
  }
  std::sort(got.begin(), got.end(), [](auto& a, auto& b) { return a.second < b.second; });
  const bool data_first = source.data_port() < source.position_port();
  EXPECT_EQ(got[data_first ? 0 : 1].first, data);
  EXPECT_EQ(got[data_first ? 0 : 1].second, source.data_port());
  EXPECT_EQ(got[data_first ? 1 : 0].first, position);
  EXPECT_EQ(source.host_clock_stamps(), 0u);
  const driver::SourceStats stats = source.stats();
  EXPECT_EQ(stats.packets, 2u);
  EXPECT_EQ(stats.bytes, 1206u + 512u);
  EXPECT_EQ(stats.kernel_drops, 0u);
}

TEST(UdpSource, TimesOutWhenNothingArrives) {
  driver::UdpSource source(loopback_options());
  driver::RawPacket p;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(source.next(p, 30ms), driver::ReadStatus::kTimeout);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 25ms);
  EXPECT_EQ(source.next(p, 0ms), driver::ReadStatus::kTimeout);
}

TEST(UdpSource, HostClockWhenKernelTimestampsAreOff) {
  auto options = loopback_options();
  options.kernel_timestamps = false;
  options.open_position_port = false;
  driver::UdpSource source(options);
  EXPECT_EQ(source.position_port(), 0);
  Sender sender;
  const int64_t before = now_ns();
  ASSERT_TRUE(sender.send(source.data_port(), payload(1206, 3)));
  driver::RawPacket p;
  ASSERT_EQ(source.next(p, 1000ms), driver::ReadStatus::kPacket);
  EXPECT_GE(p.receive_time_ns, before);
  EXPECT_LE(p.receive_time_ns, now_ns());
  EXPECT_EQ(source.host_clock_stamps(), 1u);
}

TEST(UdpSource, OtherSendersAreCountedAsForeign) {
  auto options = loopback_options();
  options.sensor_ipv4 = 0xC0A801C9;  // 192.168.1.201: not the loopback sender
  driver::UdpSource source(options);
  Sender sender;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(sender.send(source.data_port(), payload(1206, 4)));
  driver::RawPacket p;
  EXPECT_EQ(source.next(p, 50ms), driver::ReadStatus::kTimeout);
  EXPECT_EQ(source.stats().foreign_source, 3u);
  EXPECT_EQ(source.stats().ignored, 0u);
  EXPECT_EQ(source.stats().packets, 0u);
}

TEST(UdpSource, KernelDropsAreReportedWhenTheBufferOverflows) {
  auto options = loopback_options();
  options.receive_buffer_bytes = 4096;  // the kernel's minimum, a few packets
  options.open_position_port = false;
  driver::UdpSource source(options);
  EXPECT_LT(source.granted_receive_buffer(), 64 * 1024);
  Sender sender;
  constexpr int kSent = 200;
  for (int i = 0; i < kSent; ++i) sender.send(source.data_port(), payload(1206, 5));
  driver::RawPacket p;
  uint64_t received = 0;
  while (source.next(p, 50ms) == driver::ReadStatus::kPacket) ++received;
  EXPECT_GT(received, 0u);
  EXPECT_LT(received, static_cast<uint64_t>(kSent));
  // The kernel attaches its drop count to datagrams queued after the drops: one more packet.
  ASSERT_TRUE(sender.send(source.data_port(), payload(1206, 6)));
  ASSERT_EQ(source.next(p, 1000ms), driver::ReadStatus::kPacket);
  EXPECT_EQ(source.stats().kernel_drops, kSent - received);
}

TEST(UdpSource, LargeBufferRequestIsGrantedOrReported) {
  driver::UdpSource source(loopback_options());
  // Root may force the full 8 MiB (reported doubled); otherwise rmem_max caps it. Either way the
  // report is what the kernel holds, never more than twice the request.
  EXPECT_GE(source.granted_receive_buffer(), 4096);
  EXPECT_LE(source.granted_receive_buffer(), 2 * 8 * 1024 * 1024);
  if (::geteuid() == 0) {
    EXPECT_GE(source.granted_receive_buffer(), 8 * 1024 * 1024);
  }
}

TEST(UdpSource, SetupErrorsAreTyped) {
  auto bad = loopback_options();
  bad.bind_address = "not-an-address";
  EXPECT_THROW(driver::UdpSource source(bad), driver::IoError);

  auto first = loopback_options();
  first.reuse_address = false;
  first.open_position_port = false;
  driver::UdpSource taken(first);
  auto second = first;
  second.data_port = taken.data_port();
  try {
    driver::UdpSource source(second);
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(taken.data_port())), std::string::npos)
        << e.what();
  }
}

TEST(UdpSource, PortsAreExclusiveUnlessEverySocketShares) {
  auto first = loopback_options();
  first.open_position_port = false;
  EXPECT_FALSE(first.reuse_address);  // the default
  driver::UdpSource taken(first);
  auto second = first;
  second.data_port = taken.data_port();
  try {
    driver::UdpSource source(second);
    FAIL() << "a second socket took the port";
  } catch (const driver::IoError& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot bind UDP 127.0.0.1:" + std::to_string(taken.data_port()) +
                  ": Address already in use (another program receives on this port, e.g. a "
                  "second lidartagd or a sensor driver; it is bound exclusively unless every "
                  "user shares it)");
  }
  // One sharing socket is not enough: the exclusive one keeps the port.
  second.reuse_address = true;
  EXPECT_THROW(driver::UdpSource source(second), driver::IoError);

  // Both sharing: both bind, and a datagram sent to the port reaches one of them.
  first.reuse_address = true;
  driver::UdpSource a(first);
  second.data_port = a.data_port();
  driver::UdpSource b(second);
  ASSERT_TRUE(Sender().send(a.data_port(), payload(100, 1)));
  driver::RawPacket packet;
  const bool got_a = a.next(packet, 1s) == driver::ReadStatus::kPacket;
  const bool got_b = b.next(packet, got_a ? 100ms : 1s) == driver::ReadStatus::kPacket;
  EXPECT_NE(got_a, got_b);
}

std::string scratch(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartag_udp");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

// A multicast group as bind address: joined and shared, every member gets each datagram. In a
// network namespace of its own (lo with a multicast route), never on the machine's interfaces.
TEST(UdpSource, MulticastGroupIsJoinedAndSharedByEveryMember) {
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"},
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo",
                            scratch("netns"));
  driver::UdpSourceOptions o;
  o.bind_address = "239.192.0.5";
  o.data_port = 23680;
  o.open_position_port = false;
  driver::UdpSource a(o), b(o);  // shared although reuse_address is off: a group has many members
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(23680);
  to.sin_addr.s_addr = htonl(0xEFC00005);
  const auto data = payload(1206, 9);
  ASSERT_EQ(::sendto(fd, data.data(), data.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to)),
            static_cast<ssize_t>(data.size()));
  ::close(fd);
  for (driver::UdpSource* source : {&a, &b}) {
    driver::RawPacket packet;
    ASSERT_EQ(source->next(packet, 1s), driver::ReadStatus::kPacket);
    EXPECT_EQ(packet.payload.size(), data.size());
    EXPECT_EQ(packet.destination_port, 23680);
  }
}

}  // namespace
}  // namespace lidartag::velodyne
