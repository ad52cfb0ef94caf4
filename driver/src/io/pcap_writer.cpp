#include "lidartag/driver/io/pcap_writer.hpp"

#include <pcap/pcap.h>
#include <sys/time.h>

#include <algorithm>

#include "net_headers.hpp"

namespace lidartag::velodyne {
namespace {

pcap_t* as_pcap(void* p) {
  return static_cast<pcap_t*>(p);
}
pcap_dumper_t* as_dumper(void* p) {
  return static_cast<pcap_dumper_t*>(p);
}

// Fixed addresses keep the output deterministic: 60:76:88 is Velodyne's OUI.
constexpr uint8_t kSourceMac[6] = {0x60, 0x76, 0x88, 0x00, 0x00, 0x01};
constexpr uint8_t kBroadcastMac[6] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
constexpr int kSnapLength = 65535;

}  // namespace

PcapWriter::PcapWriter(const std::string& path) : path_(path) {
  pcap_t* pcap =
      pcap_open_dead_with_tstamp_precision(DLT_EN10MB, kSnapLength, PCAP_TSTAMP_PRECISION_MICRO);
  if (pcap == nullptr) throw IoError("cannot create pcap writer for '" + path + "'");
  pcap_dumper_t* dumper = pcap_dump_open(pcap, path.c_str());
  if (dumper == nullptr) {
    const std::string message = pcap_geterr(pcap);
    pcap_close(pcap);
    throw IoError("cannot create '" + path + "': " + message);
  }
  pcap_ = pcap;
  dumper_ = dumper;
  frame_.assign(net::kEthernetHeader + net::kIpv4MinHeader + net::kUdpHeader + kMaxPayload, 0);
}

PcapWriter::~PcapWriter() {
  close_quietly();
}

void PcapWriter::write_udp(std::span<const uint8_t> payload, int64_t time_ns, uint16_t dst_port,
                           uint32_t src_ipv4, uint32_t dst_ipv4, uint16_t src_port) {
  if (dumper_ == nullptr) throw IoError("write to closed pcap file '" + path_ + "'");
  if (payload.size() > kMaxPayload) {
    throw IoError("UDP payload of " + std::to_string(payload.size()) + " bytes too large for '" +
                  path_ + "'");
  }
  if (src_port == 0) src_port = dst_port;
  const size_t udp_length = net::kUdpHeader + payload.size();
  const size_t ip_length = net::kIpv4MinHeader + udp_length;
  const size_t frame_length = net::kEthernetHeader + ip_length;
  uint8_t* eth = frame_.data();
  uint8_t* ip = eth + net::kEthernetHeader;
  uint8_t* udp = ip + net::kIpv4MinHeader;

  // Ethernet II: destination, source, EtherType.
  for (int i = 0; i < 6; ++i) {
    eth[i] = kBroadcastMac[i];
    eth[6 + i] = kSourceMac[i];
  }
  net::put_be16(eth + 12, net::kEtherTypeIpv4);

  // IPv4, 20-byte header, no options, no fragmentation, TTL 64.
  ip[0] = 0x45;
  ip[1] = 0;
  net::put_be16(ip + 2, static_cast<uint16_t>(ip_length));
  net::put_be16(ip + 4, ip_id_++);
  net::put_be16(ip + 6, 0);
  ip[8] = 64;
  ip[9] = net::kProtocolUdp;
  net::put_be16(ip + 10, 0);
  net::put_be32(ip + 12, src_ipv4);
  net::put_be32(ip + 16, dst_ipv4);
  net::put_be16(ip + 10, net::fold_checksum(net::ones_sum({ip, net::kIpv4MinHeader})));

  // UDP with its checksum over the pseudo header (0 is sent as 0xFFFF, RFC 768).
  net::put_be16(udp, src_port);
  net::put_be16(udp + 2, dst_port);
  net::put_be16(udp + 4, static_cast<uint16_t>(udp_length));
  net::put_be16(udp + 6, 0);
  std::copy(payload.begin(), payload.end(), udp + net::kUdpHeader);
  uint32_t sum = net::ones_sum({ip + 12, 8});
  sum += net::kProtocolUdp;
  sum += static_cast<uint32_t>(udp_length);
  uint16_t checksum = net::fold_checksum(net::ones_sum({udp, udp_length}, sum));
  if (checksum == 0) checksum = 0xFFFF;
  net::put_be16(udp + 6, checksum);

  // Floor division so times before the epoch still give 0 <= usec < 1e6.
  int64_t usec = time_ns / 1000;
  if (time_ns % 1000 < 0) --usec;
  int64_t sec = usec / 1000000;
  int64_t usec_part = usec % 1000000;
  if (usec_part < 0) {
    usec_part += 1000000;
    --sec;
  }
  pcap_pkthdr header{};
  header.ts.tv_sec = static_cast<time_t>(sec);
  header.ts.tv_usec = static_cast<suseconds_t>(usec_part);
  header.caplen = static_cast<bpf_u_int32>(frame_length);
  header.len = static_cast<bpf_u_int32>(frame_length);
  pcap_dump(static_cast<u_char*>(dumper_), &header, frame_.data());
  ++records_;
}

void PcapWriter::close() {
  if (dumper_ == nullptr) return;
  const bool flushed = pcap_dump_flush(as_dumper(dumper_)) == 0;
  close_quietly();
  if (!flushed) throw IoError("cannot write '" + path_ + "'");
}

void PcapWriter::close_quietly() noexcept {
  if (dumper_ != nullptr) pcap_dump_close(as_dumper(dumper_));
  if (pcap_ != nullptr) pcap_close(as_pcap(pcap_));
  dumper_ = nullptr;
  pcap_ = nullptr;
}

}  // namespace lidartag::velodyne
