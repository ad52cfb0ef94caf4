#include "lidartag/driver/io/live_source.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <pcap/pcap.h>
#include <sys/socket.h>
#include <unistd.h>

#include <vector>

#include "lidartag/driver/io/udp_source.hpp"

namespace lidartag::velodyne {
namespace {

using namespace std::chrono_literals;

// Compiles `filter` for Ethernet without any device: proves the expression is valid BPF.
bool compiles(const std::string& filter) {
  pcap_t* dead = pcap_open_dead(DLT_EN10MB, 2048);
  bpf_program program{};
  const bool ok = pcap_compile(dead, &program, filter.c_str(), 1, PCAP_NETMASK_UNKNOWN) == 0;
  if (ok) pcap_freecode(&program);
  pcap_close(dead);
  return ok;
}

TEST(LiveSourceFilter, SelectsTheSensorPortsAndAddress) {
  driver::LiveSourceOptions options;
  EXPECT_EQ(driver::build_bpf_filter(options), "ip and udp and (dst port 2368 or dst port 8308)");
  options.data_port = 2369;
  options.position_port = 8309;
  options.sensor_ipv4 = 0xC0A801C9;
  const std::string filter = driver::build_bpf_filter(options);
  EXPECT_EQ(filter, "ip and udp and (dst port 2369 or dst port 8309) and src host 192.168.1.201");
  EXPECT_TRUE(compiles(filter));
  EXPECT_TRUE(compiles(driver::build_bpf_filter(driver::LiveSourceOptions{})));
}

TEST(Ipv4Text, RoundTripsDottedQuads) {
  EXPECT_EQ(driver::ipv4_to_string(0xC0A801C9), "192.168.1.201");
  EXPECT_EQ(driver::ipv4_to_string(0), "0.0.0.0");
  uint32_t a = 0;
  ASSERT_TRUE(driver::parse_ipv4_address("192.168.1.201", a));
  EXPECT_EQ(a, 0xC0A801C9u);
  ASSERT_TRUE(driver::parse_ipv4_address("255.255.255.255", a));
  EXPECT_EQ(a, 0xFFFFFFFFu);
  for (const char* bad : {"", "1.2.3", "1.2.3.4.5", "256.1.1.1", "1.2.3.x", "1..2.3", " 1.2.3.4",
                          "1.2.3.4 ", "1111.2.3.4"}) {
    EXPECT_FALSE(driver::parse_ipv4_address(bad, a)) << bad;
  }
}

TEST(LiveSource, NonexistentInterfaceIsAnIoErrorNamingIt) {
  driver::LiveSourceOptions options;
  options.interface = "lidartag-no-such-if0";
  try {
    driver::LiveSource source(options);
    FAIL() << "expected driver::IoError";
  } catch (const driver::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("lidartag-no-such-if0"), std::string::npos) << e.what();
  }
  options.interface.clear();
  EXPECT_THROW(driver::LiveSource source(options), driver::IoError);
}

TEST(LiveSource, CapturesLoopbackTrafficThroughTheFilter) {
  // Receive the packets with a socket too, so the kernel has a listener for them.
  driver::UdpSourceOptions udp_options;
  udp_options.bind_address = "127.0.0.1";
  udp_options.data_port = 0;
  udp_options.position_port = 0;
  driver::UdpSource receiver(udp_options);

  driver::LiveSourceOptions options;
  options.interface = "lo";
  options.data_port = receiver.data_port();
  options.position_port = receiver.position_port();
  options.sensor_ipv4 = 0x7F000001;
  std::unique_ptr<driver::LiveSource> live;
  try {
    live = std::make_unique<driver::LiveSource>(options);
  } catch (const driver::IoError& e) {
    GTEST_SKIP() << "cannot capture on lo here (needs CAP_NET_RAW): " << e.what();
  }
  EXPECT_EQ(live->link_type(), DLT_EN10MB);

  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  auto send_to = [&](uint16_t port, size_t size, uint8_t fill) {
    std::vector<uint8_t> payload(size, fill);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::sendto(fd, payload.data(), payload.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to));
  };
  send_to(receiver.position_port() + 1000, 100, 0x11);  // not a sensor port: filtered out
  send_to(receiver.data_port(), 1206, 0xAB);
  send_to(receiver.position_port(), 512, 0xCD);
  ::close(fd);

  std::vector<std::pair<size_t, uint16_t>> got;
  driver::RawPacket p;
  for (int i = 0; i < 2; ++i) {
    ASSERT_EQ(live->next(p, 2000ms), driver::ReadStatus::kPacket);
    ASSERT_FALSE(p.payload.empty());
    EXPECT_EQ(p.payload[0], p.payload.size() == 1206 ? 0xAB : 0xCD);
    EXPECT_EQ(p.source_ipv4, 0x7F000001u);
    EXPECT_GT(p.receive_time_ns, 0);
    got.emplace_back(p.payload.size(), p.destination_port);
  }
  EXPECT_EQ(got[0], std::make_pair(size_t{1206}, receiver.data_port()));
  EXPECT_EQ(got[1], std::make_pair(size_t{512}, receiver.position_port()));
  EXPECT_EQ(live->next(p, 50ms), driver::ReadStatus::kTimeout);  // the third packet did not pass
  EXPECT_EQ(live->stats().packets, 2u);
  EXPECT_EQ(live->stats().kernel_drops, 0u);
}

}  // namespace
}  // namespace lidartag::velodyne
