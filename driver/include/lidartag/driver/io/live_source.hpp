// Captures a sensor's packets from a network interface with libpcap and a BPF filter: for hosts
// where binding the sensor's ports is not possible (another program owns them) or traffic must be
// observed without receiving it. Needs CAP_NET_RAW (or root).
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver {

struct LiveSourceOptions {
  std::string interface;  // e.g. "eth0"; "any" captures on every interface (cooked frames)
  uint16_t data_port = kDefaultDataPort;
  uint16_t position_port = kDefaultPositionPort;
  // Only packets from this sender (IPv4, host byte order); also part of the BPF filter.
  std::optional<uint32_t> sensor_ipv4;
  // Promiscuous mode: needed only when the sensor unicasts to another host on a shared segment.
  bool promiscuous = false;
  // Bytes kept per frame: a 1248-byte data frame plus VLAN tags and IPv4 options fits.
  int snaplen = 2048;
  // Kernel capture buffer, bytes (the ring libpcap asks for).
  int buffer_bytes = 8 * 1024 * 1024;
  // Deliver each packet as it arrives instead of batching (lower latency, more wake-ups).
  bool immediate = true;
};

// The BPF filter expression for `options`, e.g.
// "ip and udp and (dst port 2368 or dst port 8308) and src host 192.168.1.201".
std::string build_bpf_filter(const LiveSourceOptions& options);

class LiveSource final : public PacketSource {
 public:
  // Opens and activates the capture; throws IoError naming the interface with libpcap's message
  // (no such device, permission denied, filter rejected, unsupported link type).
  explicit LiveSource(LiveSourceOptions options);
  ~LiveSource() override;
  LiveSource(const LiveSource&) = delete;
  LiveSource& operator=(const LiveSource&) = delete;

  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override;
  // kernel_drops: packets the kernel or the interface dropped (pcap_stats ps_drop + ps_ifdrop).
  SourceStats stats() const override;

  int link_type() const { return link_type_; }
  const std::string& filter() const { return filter_; }

 private:
  LiveSourceOptions options_;
  std::string filter_;
  void* pcap_ = nullptr;  // pcap_t*
  int link_type_ = 0;
  int fd_ = -1;  // selectable descriptor for waiting with a timeout
  SourceStats stats_{};
};

}  // namespace lidartag::driver
