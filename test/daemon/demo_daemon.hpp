// For the tests that drive lidartagd as a program: the daemon, the demo configuration and capture,
// a free loopback UDP port, and the demo sent to loopback at its recorded pace. The including
// target defines LIDARTAGD_PATH and links lidartag_driver_io.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "lidartag/driver/io/pcap_source.hpp"

namespace lidartag::test {

inline const std::string kDaemon = LIDARTAGD_PATH;
inline const std::string kDemoConfig = LIDARTAG_SOURCE_DIR "/config/demo.yaml";
inline const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";

// A loopback UDP port nobody holds (bound and released at once).
inline uint16_t free_udp_port() {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  socklen_t len = sizeof(addr);
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

// Sends the demo's packets to 127.0.0.1 at their recorded pace (one pass: bounded in count and
// time). Returns the number sent.
// `from`: the sender's address (host byte order; any loopback address), 0: the kernel's choice.
inline size_t send_demo(uint16_t data_port, uint16_t position_port, uint32_t from = 0) {
  using namespace std::chrono_literals;
  driver::PcapSourceOptions pacing;
  pacing.pacing = driver::ReplayPacing::kCaptureTime;
  driver::PcapSource source(kDemo, pacing);
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (from != 0) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    local.sin_addr.s_addr = htonl(from);
    if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof(local)) != 0) {
      close(fd);
      return 0;
    }
  }
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  driver::RawPacket packet;
  size_t sent = 0;
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - start < 30s) {
    const auto status = source.next(packet, 100ms);
    if (status == driver::ReadStatus::kTimeout) continue;
    if (status != driver::ReadStatus::kPacket) break;
    to.sin_port =
        htons(packet.destination_port == driver::kDefaultDataPort ? data_port : position_port);
    if (sendto(fd, packet.payload.data(), packet.payload.size(), 0,
               reinterpret_cast<sockaddr*>(&to),
               sizeof(to)) == static_cast<ssize_t>(packet.payload.size())) {
      ++sent;
    }
  }
  close(fd);
  return sent;
}

}  // namespace lidartag::test
