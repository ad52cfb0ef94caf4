// One interface for live sockets, live interface capture and pcap replay: each packet carries its
// receive (or capture) time, so recorded captures drive the tests and the daemon alike.
#pragma once

#include <chrono>
#include <cstdint>
#include <span>
#include <string>

namespace lidartag::driver {

// The UDP ports a source reads unless told otherwise: a sensor's data port and its auxiliary one
// (Velodyne's position packets). The defaults are Velodyne's (velodyne/packet.hpp names them).
inline constexpr uint16_t kDefaultDataPort = 2368;
inline constexpr uint16_t kDefaultPositionPort = 8308;

struct RawPacket {
  std::span<const uint8_t> payload;  // UDP payload; valid until the next call to next()
  int64_t receive_time_ns = 0;       // host receive time or capture timestamp, ns since epoch
  uint32_t source_ipv4 = 0;          // sender address, host byte order (0 if unknown)
  uint16_t destination_port = 0;
};

// Receive times a replay source accepts: [0, 2^32 s), what classic pcap's 32-bit seconds can hold
// (until 2106). Later or negative times come from corrupt timestamps (pcapng and LCM carry 64 bits)
// and are counted as malformed, so that arithmetic on packet times never overflows.
inline constexpr int64_t kMaxReceiveTimeNs = 4'294'967'296LL * 1'000'000'000LL;

enum class ReadStatus : uint8_t { kPacket, kTimeout, kEnd, kError };

struct SourceStats {
  uint64_t packets = 0;  // UDP payloads delivered
  uint64_t bytes = 0;
  uint64_t ignored = 0;       // other traffic: wrong port, protocol, not IPv4/UDP, fragments
  uint64_t truncated = 0;     // records shorter than their headers claim (never read past)
  uint64_t malformed = 0;     // corrupt headers
  uint64_t kernel_drops = 0;  // reported by the kernel / libpcap
  uint64_t errors = 0;        // read errors
  // Packets to the sensor's ports from another sender than the configured sensor address
  // (filtered out, not in `ignored`).
  uint64_t foreign_source = 0;
  // Packets (a bag's sources: messages of the topics read) outside the time window asked for
  // (driver::ScanSourceOptions::start_s, duration_s), read and passed over.
  uint64_t outside_window = 0;
};

class PacketSource {
 public:
  virtual ~PacketSource() = default;
  // Next packet, or kTimeout after `timeout`, kEnd at the end of a finite source.
  virtual ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) = 0;
  virtual SourceStats stats() const = 0;
  // Why the source ended before its end (a corrupt record that cuts a replay short, a read
  // error), naming what was not read; empty while nothing was lost that way.
  virtual std::string error() const { return {}; }
};

}  // namespace lidartag::driver
