// Byte-level helpers for the Ethernet / IPv4 / UDP headers the pcap reader and writer handle.
// Network byte order (big-endian) on the wire.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace lidartag::driver::net {

inline constexpr size_t kEthernetHeader = 14;
inline constexpr size_t kVlanTag = 4;
inline constexpr size_t kIpv4MinHeader = 20;
inline constexpr size_t kUdpHeader = 8;
inline constexpr uint16_t kEtherTypeIpv4 = 0x0800;
inline constexpr uint16_t kEtherTypeVlan = 0x8100;  // 802.1Q
inline constexpr uint16_t kEtherTypeQinQ = 0x88A8;  // 802.1ad outer tag
inline constexpr uint16_t kEtherTypeQinQOld = 0x9100;
inline constexpr uint8_t kProtocolUdp = 17;

inline uint16_t be16(const uint8_t* p) {
  return static_cast<uint16_t>((p[0] << 8) | p[1]);
}
inline uint32_t be32(const uint8_t* p) {
  return (static_cast<uint32_t>(p[0]) << 24) | (static_cast<uint32_t>(p[1]) << 16) |
         (static_cast<uint32_t>(p[2]) << 8) | static_cast<uint32_t>(p[3]);
}
inline void put_be16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v >> 8);
  p[1] = static_cast<uint8_t>(v & 0xFF);
}
inline void put_be32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>((v >> (24 - 8 * i)) & 0xFF);
}

// Ones' complement sum of 16-bit big-endian words (RFC 1071), not yet folded or inverted.
inline uint32_t ones_sum(std::span<const uint8_t> bytes, uint32_t sum = 0) {
  size_t i = 0;
  for (; i + 1 < bytes.size(); i += 2) sum += be16(bytes.data() + i);
  if (i < bytes.size()) sum += static_cast<uint32_t>(bytes[i]) << 8;
  return sum;
}
inline uint16_t fold_checksum(uint32_t sum) {
  while (sum >> 16) sum = (sum & 0xFFFF) + (sum >> 16);
  return static_cast<uint16_t>(~sum & 0xFFFF);
}

}  // namespace lidartag::driver::net
