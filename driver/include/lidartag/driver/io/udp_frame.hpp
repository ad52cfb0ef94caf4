// Finds the UDP payload inside one captured link-layer frame, for every link type the pcap and live
// sources accept. Pure and bounds-checked: never reads past `caplen`.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver {

// libpcap DLT_ values of the supported link types (the numbers of <pcap/dlt.h> on Linux).
enum class LinkType : int {
  kEthernet = 1,     // DLT_EN10MB, with 802.1Q / 802.1ad VLAN tags (any depth up to 4)
  kRaw = 12,         // DLT_RAW (LINKTYPE_RAW 101 in files): IPv4 or IPv6, no link header
  kLinuxSll = 113,   // DLT_LINUX_SLL, Linux cooked capture v1 (16-byte header)
  kIpv4 = 228,       // DLT_IPV4 (LINKTYPE_IPV4)
  kLinuxSll2 = 276,  // DLT_LINUX_SLL2, Linux cooked capture v2 (20-byte header)
};

// Whether `dlt` (a libpcap DLT_ value) is one of the LinkType values.
bool is_supported_link_type(int dlt);
std::string link_type_name(int dlt);

enum class FrameStatus : uint8_t {
  kUdp,        // a whole UDP payload: `UdpView` is filled
  kIgnored,    // not IPv4/UDP (ARP, IPv6, TCP, ...)
  kFragment,   // an IPv4 fragment (payload incomplete by design; not reassembled)
  kTruncated,  // the capture holds fewer bytes than the headers say (snap length, cut file)
  kMalformed,  // headers contradict themselves (bad version, IHL < 5, lengths inconsistent)
};

struct UdpView {
  std::span<const uint8_t> payload;  // points into the frame
  uint32_t source_ipv4 = 0;          // host byte order
  uint32_t destination_ipv4 = 0;
  uint16_t source_port = 0;
  uint16_t destination_port = 0;
};

// `frame` holds the captured bytes (caplen). IPv4 header options are skipped using IHL; Ethernet
// padding past the IPv4 total length is ignored.
[[nodiscard]] FrameStatus parse_udp_frame(LinkType link, std::span<const uint8_t> frame,
                                          UdpView& out);

// What the sources deliver: UDP to the data or the position port, from `sensor` when one is set.
struct UdpFilter {
  uint16_t data_port = 0;
  uint16_t position_port = 0;
  std::optional<uint32_t> sensor_ipv4;
};

// Parses one captured frame and tells whether it is a packet to deliver (`udp` filled); anything
// else is counted in `stats` (ignored, truncated, malformed; fragments count as ignored).
[[nodiscard]] bool accept_udp_frame(LinkType link, std::span<const uint8_t> frame,
                                    const UdpFilter& filter, UdpView& udp, SourceStats& stats,
                                    FrameStatus& status);

// Dotted quad of a host-byte-order IPv4 address, and its inverse (false unless exactly a dotted
// quad of four numbers 0..255).
std::string ipv4_to_string(uint32_t address);
bool parse_ipv4_address(std::string_view text, uint32_t& address);

}  // namespace lidartag::driver
