// Builds capture files byte by byte for the reader tests: classic pcap (any link type, micro- or
// nanosecond magic), minimal pcapng, and Ethernet / Linux cooked / raw frames around IPv4 + UDP.
#pragma once

#include <cstdint>
#include <fstream>
#include <span>
#include <string>
#include <vector>

namespace lidartag::test {

using Bytes = std::vector<uint8_t>;

inline void put_le16(Bytes& b, uint16_t v) {
  b.push_back(static_cast<uint8_t>(v & 0xFF));
  b.push_back(static_cast<uint8_t>(v >> 8));
}
inline void put_le32(Bytes& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>((v >> (8 * i)) & 0xFF));
}
inline void put_be16(Bytes& b, uint16_t v) {
  b.push_back(static_cast<uint8_t>(v >> 8));
  b.push_back(static_cast<uint8_t>(v & 0xFF));
}
inline void put_be32(Bytes& b, uint32_t v) {
  for (int i = 3; i >= 0; --i) b.push_back(static_cast<uint8_t>((v >> (8 * i)) & 0xFF));
}
inline void append(Bytes& b, std::span<const uint8_t> more) {
  b.insert(b.end(), more.begin(), more.end());
}

inline Bytes payload_bytes(size_t n, uint8_t seed) {
  Bytes p(n);
  for (size_t i = 0; i < n; ++i) p[i] = static_cast<uint8_t>(seed + i * 13);
  return p;
}

struct Ipv4Options {
  uint32_t src = 0xC0A801C9;
  uint32_t dst = 0xFFFFFFFF;
  uint8_t protocol = 17;
  size_t option_words = 0;  // 32-bit words of IPv4 options (IHL = 5 + this)
  uint16_t flags_fragment = 0;
  int total_length_delta = 0;  // corrupt the total length by this much
  int udp_length_delta = 0;    // corrupt the UDP length by this much
  uint8_t version_ihl_override = 0;
};

// IPv4 + UDP datagram (IPv4 checksum left 0: readers must not depend on it).
inline Bytes ipv4_udp(std::span<const uint8_t> payload, uint16_t dst_port, Ipv4Options o = {},
                      uint16_t src_port = 0) {
  if (src_port == 0) src_port = dst_port;
  const size_t header = 20 + 4 * o.option_words;
  const size_t udp_length = 8 + payload.size();
  Bytes b;
  b.push_back(o.version_ihl_override ? o.version_ihl_override
                                     : static_cast<uint8_t>(0x40 | (header / 4)));
  b.push_back(0);
  put_be16(b, static_cast<uint16_t>(static_cast<int>(header + udp_length) + o.total_length_delta));
  put_be16(b, 0x1234);
  put_be16(b, o.flags_fragment);
  b.push_back(64);
  b.push_back(o.protocol);
  put_be16(b, 0);
  put_be32(b, o.src);
  put_be32(b, o.dst);
  for (size_t i = 0; i < o.option_words; ++i) put_be32(b, 0x01010101);  // NOP options
  put_be16(b, src_port);
  put_be16(b, dst_port);
  put_be16(b, static_cast<uint16_t>(static_cast<int>(udp_length) + o.udp_length_delta));
  put_be16(b, 0);
  append(b, payload);
  return b;
}

// Ethernet II around `inner` with the given VLAN tags (TPIDs, outermost first).
inline Bytes ethernet(std::span<const uint8_t> inner, uint16_t ethertype = 0x0800,
                      std::vector<uint16_t> vlan_tpids = {}) {
  Bytes b = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x60, 0x76, 0x88, 0x00, 0x00, 0x01};
  for (uint16_t tpid : vlan_tpids) {
    put_be16(b, tpid);
    put_be16(b, 0x0064);  // TCI: VLAN 100
  }
  put_be16(b, ethertype);
  append(b, inner);
  return b;
}

inline Bytes linux_sll(std::span<const uint8_t> inner, uint16_t protocol = 0x0800) {
  Bytes b;
  put_be16(b, 0);  // packet type: to us
  put_be16(b, 1);  // ARPHRD_ETHER
  put_be16(b, 6);
  for (int v : {0x60, 0x76, 0x88, 0x00, 0x00, 0x01, 0x00, 0x00})
    b.push_back(static_cast<uint8_t>(v));
  put_be16(b, protocol);
  append(b, inner);
  return b;
}

inline Bytes linux_sll2(std::span<const uint8_t> inner, uint16_t protocol = 0x0800) {
  Bytes b;
  put_be16(b, protocol);
  put_be16(b, 0);  // reserved
  put_be32(b, 2);  // interface index
  put_be16(b, 1);  // ARPHRD_ETHER
  b.push_back(0);  // packet type
  b.push_back(6);  // address length
  for (int v : {0x60, 0x76, 0x88, 0x00, 0x00, 0x01, 0x00, 0x00})
    b.push_back(static_cast<uint8_t>(v));
  append(b, inner);
  return b;
}

struct Record {
  Bytes frame;
  int64_t time_ns = 0;
  size_t caplen_cut = 0;  // bytes dropped from the end of the captured data (len stays whole)
};

// Classic pcap; `nano` selects the nanosecond magic.
inline Bytes classic_pcap(uint32_t linktype, const std::vector<Record>& records, bool nano = false,
                          uint32_t snaplen = 65535) {
  Bytes b;
  put_le32(b, nano ? 0xA1B23C4D : 0xA1B2C3D4);
  put_le16(b, 2);
  put_le16(b, 4);
  put_le32(b, 0);
  put_le32(b, 0);
  put_le32(b, snaplen);
  put_le32(b, linktype);
  for (const Record& r : records) {
    const uint32_t len = static_cast<uint32_t>(r.frame.size());
    const uint32_t caplen = static_cast<uint32_t>(r.frame.size() - r.caplen_cut);
    put_le32(b, static_cast<uint32_t>(r.time_ns / 1'000'000'000));
    const int64_t frac = r.time_ns % 1'000'000'000;
    put_le32(b, static_cast<uint32_t>(nano ? frac : frac / 1000));
    put_le32(b, caplen);
    put_le32(b, len);
    b.insert(b.end(), r.frame.begin(), r.frame.begin() + static_cast<std::ptrdiff_t>(caplen));
  }
  return b;
}

// Minimal pcapng: section header, one interface (with if_tsresol when `tsresol` != 6, the default
// microseconds), one enhanced packet block per record.
inline Bytes pcapng(uint16_t linktype, const std::vector<Record>& records, uint8_t tsresol = 6) {
  Bytes b;
  auto pad4 = [](Bytes& x) {
    while (x.size() % 4) x.push_back(0);
  };
  // Section Header Block.
  put_le32(b, 0x0A0D0D0A);
  put_le32(b, 28);
  put_le32(b, 0x1A2B3C4D);
  put_le16(b, 1);
  put_le16(b, 0);
  put_le32(b, 0xFFFFFFFF);  // section length unknown (-1)
  put_le32(b, 0xFFFFFFFF);
  put_le32(b, 28);
  // Interface Description Block.
  Bytes idb;
  put_le16(idb, linktype);
  put_le16(idb, 0);
  put_le32(idb, 65535);
  if (tsresol != 6) {
    put_le16(idb, 9);  // if_tsresol
    put_le16(idb, 1);
    idb.push_back(tsresol);
    pad4(idb);
    put_le16(idb, 0);  // opt_endofopt
    put_le16(idb, 0);
  }
  put_le32(b, 1);
  put_le32(b, static_cast<uint32_t>(12 + idb.size()));
  append(b, idb);
  put_le32(b, static_cast<uint32_t>(12 + idb.size()));
  // Enhanced Packet Blocks.
  uint64_t per_second = 1;
  for (int i = 0; i < tsresol; ++i) per_second *= 10;
  for (const Record& r : records) {
    const uint64_t ticks = static_cast<uint64_t>(r.time_ns) / (1'000'000'000 / per_second);
    Bytes epb;
    put_le32(epb, 0);  // interface 0
    put_le32(epb, static_cast<uint32_t>(ticks >> 32));
    put_le32(epb, static_cast<uint32_t>(ticks & 0xFFFFFFFF));
    const size_t caplen = r.frame.size() - r.caplen_cut;
    put_le32(epb, static_cast<uint32_t>(caplen));
    put_le32(epb, static_cast<uint32_t>(r.frame.size()));
    epb.insert(epb.end(), r.frame.begin(), r.frame.begin() + static_cast<std::ptrdiff_t>(caplen));
    pad4(epb);
    put_le32(b, 6);
    put_le32(b, static_cast<uint32_t>(12 + epb.size()));
    append(b, epb);
    put_le32(b, static_cast<uint32_t>(12 + epb.size()));
  }
  return b;
}

inline void write_file(const std::string& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

}  // namespace lidartag::test
