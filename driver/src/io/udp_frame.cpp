#include "lidartag/driver/io/udp_frame.hpp"

#include "net_headers.hpp"

namespace lidartag::driver {
namespace {

constexpr size_t kSllHeader = 16;
constexpr size_t kSll2Header = 20;
constexpr int kMaxVlanTags = 4;

bool is_vlan(uint16_t type) {
  return type == net::kEtherTypeVlan || type == net::kEtherTypeQinQ ||
         type == net::kEtherTypeQinQOld;
}

FrameStatus parse_ipv4(std::span<const uint8_t> ip, UdpView& out) {
  if (ip.empty()) return FrameStatus::kTruncated;
  if ((ip[0] >> 4) != 4) return FrameStatus::kMalformed;
  const size_t header = static_cast<size_t>(ip[0] & 0x0F) * 4;  // IHL: options included
  if (header < net::kIpv4MinHeader) return FrameStatus::kMalformed;
  if (ip.size() < header) return FrameStatus::kTruncated;
  const size_t total = net::be16(ip.data() + 2);
  if (total < header) return FrameStatus::kMalformed;
  if (ip[9] != net::kProtocolUdp) return FrameStatus::kIgnored;
  const uint16_t fragment = net::be16(ip.data() + 6);
  if ((fragment & 0x2000) != 0 || (fragment & 0x1FFF) != 0) return FrameStatus::kFragment;
  // UDP header, then the payload bounded by both the UDP and the IPv4 lengths.
  if (total < header + net::kUdpHeader) return FrameStatus::kMalformed;
  if (ip.size() < header + net::kUdpHeader) return FrameStatus::kTruncated;
  const uint8_t* udp = ip.data() + header;
  const size_t udp_length = net::be16(udp + 4);
  if (udp_length < net::kUdpHeader || udp_length > total - header) return FrameStatus::kMalformed;
  if (ip.size() < header + udp_length) return FrameStatus::kTruncated;
  out.source_ipv4 = net::be32(ip.data() + 12);
  out.destination_ipv4 = net::be32(ip.data() + 16);
  out.source_port = net::be16(udp);
  out.destination_port = net::be16(udp + 2);
  out.payload = ip.subspan(header + net::kUdpHeader, udp_length - net::kUdpHeader);
  return FrameStatus::kUdp;
}

// From the EtherType at `type_offset`: skips VLAN tags (TCI + inner type), then hands IPv4 on.
FrameStatus parse_ethertype(std::span<const uint8_t> frame, size_t type_offset, UdpView& out) {
  if (frame.size() < type_offset + 2) return FrameStatus::kTruncated;
  uint16_t type = net::be16(frame.data() + type_offset);
  size_t offset = type_offset + 2;
  for (int tags = 0; is_vlan(type); ++tags) {
    if (tags == kMaxVlanTags) return FrameStatus::kMalformed;
    if (frame.size() < offset + net::kVlanTag) return FrameStatus::kTruncated;
    type = net::be16(frame.data() + offset + 2);
    offset += net::kVlanTag;
  }
  if (type != net::kEtherTypeIpv4) return FrameStatus::kIgnored;
  return parse_ipv4(frame.subspan(offset), out);
}

}  // namespace

bool is_supported_link_type(int dlt) {
  switch (static_cast<LinkType>(dlt)) {
    case LinkType::kEthernet:
    case LinkType::kRaw:
    case LinkType::kLinuxSll:
    case LinkType::kIpv4:
    case LinkType::kLinuxSll2:
      return true;
  }
  return false;
}

std::string link_type_name(int dlt) {
  switch (static_cast<LinkType>(dlt)) {
    case LinkType::kEthernet:
      return "Ethernet";
    case LinkType::kRaw:
      return "raw IP";
    case LinkType::kLinuxSll:
      return "Linux cooked capture";
    case LinkType::kIpv4:
      return "raw IPv4";
    case LinkType::kLinuxSll2:
      return "Linux cooked capture v2";
  }
  return "link type " + std::to_string(dlt);
}

std::string ipv4_to_string(uint32_t a) {
  return std::to_string(a >> 24) + "." + std::to_string((a >> 16) & 0xFF) + "." +
         std::to_string((a >> 8) & 0xFF) + "." + std::to_string(a & 0xFF);
}

bool parse_ipv4_address(std::string_view text, uint32_t& address) {
  uint32_t result = 0;
  int parts = 0;
  size_t i = 0;
  while (parts < 4) {
    if (i >= text.size() || text[i] < '0' || text[i] > '9') return false;
    uint32_t value = 0;
    size_t digits = 0;
    while (i < text.size() && text[i] >= '0' && text[i] <= '9' && digits < 4) {
      value = value * 10 + static_cast<uint32_t>(text[i] - '0');
      ++i;
      ++digits;
    }
    if (value > 255 || digits > 3) return false;
    result = (result << 8) | value;
    ++parts;
    if (parts < 4) {
      if (i >= text.size() || text[i] != '.') return false;
      ++i;
    }
  }
  if (i != text.size()) return false;
  address = result;
  return true;
}

FrameStatus parse_udp_frame(LinkType link, std::span<const uint8_t> frame, UdpView& out) {
  switch (link) {
    case LinkType::kEthernet:
      if (frame.size() < net::kEthernetHeader) return FrameStatus::kTruncated;
      return parse_ethertype(frame, 12, out);
    case LinkType::kLinuxSll:
      // Protocol at 14; a VLAN tag, when libpcap keeps it, follows the 16-byte header.
      if (frame.size() < kSllHeader) return FrameStatus::kTruncated;
      return parse_ethertype(frame, 14, out);
    case LinkType::kLinuxSll2: {
      // The protocol comes first in v2; a VLAN tag follows the 20-byte header as TCI + inner
      // EtherType, so parsing resumes at that inner type.
      if (frame.size() < kSll2Header) return FrameStatus::kTruncated;
      const uint16_t type = net::be16(frame.data());
      if (type == net::kEtherTypeIpv4) return parse_ipv4(frame.subspan(kSll2Header), out);
      if (!is_vlan(type)) return FrameStatus::kIgnored;
      return parse_ethertype(frame.subspan(kSll2Header), 2, out);
    }
    case LinkType::kRaw:
      if (frame.empty()) return FrameStatus::kTruncated;
      if ((frame[0] >> 4) != 4) return FrameStatus::kIgnored;  // IPv6
      return parse_ipv4(frame, out);
    case LinkType::kIpv4:
      return parse_ipv4(frame, out);
  }
  return FrameStatus::kIgnored;
}

bool accept_udp_frame(LinkType link, std::span<const uint8_t> frame, const UdpFilter& filter,
                      UdpView& udp, SourceStats& stats, FrameStatus& status) {
  status = parse_udp_frame(link, frame, udp);
  switch (status) {
    case FrameStatus::kUdp:
      break;
    case FrameStatus::kIgnored:
    case FrameStatus::kFragment:
      ++stats.ignored;
      return false;
    case FrameStatus::kTruncated:
      ++stats.truncated;
      return false;
    case FrameStatus::kMalformed:
      ++stats.malformed;
      return false;
  }
  if (udp.destination_port != filter.data_port && udp.destination_port != filter.position_port) {
    ++stats.ignored;
    return false;
  }
  if (filter.sensor_ipv4 && udp.source_ipv4 != *filter.sensor_ipv4) {
    ++stats.foreign_source;  // to the sensor's port, from another sender
    return false;
  }
  return true;
}

}  // namespace lidartag::driver
