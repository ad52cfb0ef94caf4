// Writes UDP payloads as a classic libpcap file (link type Ethernet, microsecond timestamps), each
// wrapped in a real Ethernet II + IPv4 + UDP frame with valid checksums, so the file reads like a
// capture of a sensor (Wireshark, tcpdump, PcapSource). Output is deterministic: the same calls
// give the same bytes (the IPv4 identification is a per-file counter, MAC addresses are fixed).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::velodyne {

class PcapWriter {
 public:
  static constexpr uint32_t kDefaultSourceIpv4 = 0xC0A801C9;  // 192.168.1.201, a Velodyne default
  static constexpr uint32_t kBroadcastIpv4 = 0xFFFFFFFF;
  static constexpr size_t kMaxPayload = 65507;  // largest UDP payload in one IPv4 datagram

  // Creates (truncates) `path`. Throws IoError with the path and libpcap's message on failure.
  explicit PcapWriter(const std::string& path);
  ~PcapWriter();
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;

  // Appends one frame carrying `payload` from src_ipv4:src_port to dst_ipv4:dst_port (addresses in
  // host byte order; src_port 0 = same as dst_port, as Velodyne sensors do). `time_ns` (ns since
  // the epoch) becomes the record timestamp, truncated to microseconds. Throws IoError when the
  // writer is closed or the payload exceeds kMaxPayload.
  void write_udp(std::span<const uint8_t> payload, int64_t time_ns, uint16_t dst_port,
                 uint32_t src_ipv4 = kDefaultSourceIpv4, uint32_t dst_ipv4 = kBroadcastIpv4,
                 uint16_t src_port = 0);

  // Flushes and closes the file; throws IoError if the data could not be written. Idempotent.
  void close();
  bool is_open() const { return dumper_ != nullptr; }
  uint64_t records() const { return records_; }
  const std::string& path() const { return path_; }

 private:
  void close_quietly() noexcept;

  std::string path_;
  void* pcap_ = nullptr;    // pcap_t*, kept opaque so users need no libpcap headers
  void* dumper_ = nullptr;  // pcap_dumper_t*
  uint64_t records_ = 0;
  uint16_t ip_id_ = 0;
  std::vector<uint8_t> frame_;  // reused for every record
};

}  // namespace lidartag::velodyne
