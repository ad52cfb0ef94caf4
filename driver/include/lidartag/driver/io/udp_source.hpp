// Receives a sensor's UDP packets on its data and position ports (Boost.Asio sockets, read with
// recvmsg for kernel receive timestamps and drop counts). One UdpSource per sensor; several
// sensors use several sources on different ports.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver {

struct UdpSourceOptions {
  // Local IPv4 address to bind; 0.0.0.0 receives on every interface (sensors broadcast). A
  // multicast group (224.0.0.0/4) is bound and joined (on the interface the routing table picks
  // for it), and its ports are always shared (reuse_address), as every member gets each packet.
  std::string bind_address = "0.0.0.0";
  // 0 lets the kernel choose a free port (tests); read the result with data_port().
  uint16_t data_port = kDefaultDataPort;
  uint16_t position_port = kDefaultPositionPort;
  bool open_position_port = true;  // false: data only
  // Only datagrams from this sender (IPv4, host byte order) are delivered; others are
  // counted in `foreign_source`.
  std::optional<uint32_t> sensor_ipv4;
  // Requested kernel receive buffer per socket, bytes. 8 MiB holds ~1 s of VLS-128 data, enough
  // to ride out scheduling hiccups. The kernel caps it at net.core.rmem_max unless the process may
  // force it (CAP_NET_ADMIN); see granted_receive_buffer().
  int receive_buffer_bytes = 8 * 1024 * 1024;
  // Kernel receive timestamps (SO_TIMESTAMPNS); when unavailable the host clock at read time.
  bool kernel_timestamps = true;
  // SO_REUSEADDR: share the ports with other sockets that set it too. Off, a port in use is an
  // error at construction, so that a second receiver cannot take a sensor's unicast packets
  // unnoticed (with sharing, Linux gives each unicast datagram to one socket only; broadcast and
  // multicast datagrams reach all). UDP has no lingering sockets for it to help with.
  bool reuse_address = false;
  // With reuse_address: the sender addresses (host byte order) of every socket of this process
  // that shares these ports, in the order they are opened, this one's among them. Each unicast
  // datagram then goes to the socket of its sender (SO_REUSEPORT, a classic BPF program steering
  // by source address) instead of to whichever socket the kernel picks; broadcast and multicast
  // datagrams still reach every socket. Empty: no steering.
  std::vector<uint32_t> steer_senders;
};

class UdpSource final : public PacketSource {
 public:
  // Binds the sockets (and joins a multicast group); throws IoError naming the address and port on
  // failure, e.g. a port another program uses.
  explicit UdpSource(UdpSourceOptions options = {});
  ~UdpSource() override;
  UdpSource(const UdpSource&) = delete;
  UdpSource& operator=(const UdpSource&) = delete;

  // Waits up to `timeout` for a datagram on either port (alternating when both have data).
  // Never kEnd. kError on a socket error (counted).
  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override;
  SourceStats stats() const override;

  uint16_t data_port() const { return data_port_; }
  uint16_t position_port() const { return position_port_; }  // 0 if not opened
  // Receive buffer the kernel granted, bytes, as getsockopt(SO_RCVBUF) reports it (Linux doubles
  // the requested value for its bookkeeping, so a granted request reads as twice the size).
  int granted_receive_buffer() const { return granted_buffer_; }
  bool kernel_timestamps_active() const { return timestamps_active_; }
  // Datagrams whose time came from the host clock (no kernel timestamp attached).
  uint64_t host_clock_stamps() const { return host_clock_stamps_; }

 private:
  struct Impl;
  struct Socket;
  ReadStatus receive(Socket& socket, RawPacket& out);

  std::unique_ptr<Impl> impl_;
  UdpSourceOptions options_;
  uint16_t data_port_ = 0, position_port_ = 0;
  int granted_buffer_ = 0;
  bool timestamps_active_ = false;
  SourceStats stats_{};
  uint64_t host_clock_stamps_ = 0;
  size_t next_socket_ = 0;
};

}  // namespace lidartag::driver
