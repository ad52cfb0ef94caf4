#include "lidartag/driver/io/live_source.hpp"

#include <pcap/pcap.h>
#include <poll.h>

#include <cerrno>
#include <cstdio>

#include "lidartag/driver/io/udp_frame.hpp"

namespace lidartag::driver {
namespace {

pcap_t* as_pcap(void* p) {
  return static_cast<pcap_t*>(p);
}

}  // namespace

std::string build_bpf_filter(const LiveSourceOptions& options) {
  std::string filter = "ip and udp and (dst port " + std::to_string(options.data_port) +
                       " or dst port " + std::to_string(options.position_port) + ")";
  if (options.sensor_ipv4) filter += " and src host " + ipv4_to_string(*options.sensor_ipv4);
  return filter;
}

LiveSource::LiveSource(LiveSourceOptions options)
    : options_(std::move(options)), filter_(build_bpf_filter(options_)) {
  const std::string& name = options_.interface;
  if (name.empty()) throw IoError("live capture needs an interface name");
  char errbuf[PCAP_ERRBUF_SIZE] = {};
  pcap_t* pcap = pcap_create(name.c_str(), errbuf);
  if (pcap == nullptr) throw IoError("cannot capture on '" + name + "': " + errbuf);
  auto fail = [&](const std::string& what) {
    std::string message = "cannot capture on '" + name + "': " + what;
    pcap_close(pcap);
    throw IoError(message);
  };
  pcap_set_snaplen(pcap, options_.snaplen);
  pcap_set_promisc(pcap, options_.promiscuous ? 1 : 0);
  pcap_set_immediate_mode(pcap, options_.immediate ? 1 : 0);
  pcap_set_buffer_size(pcap, options_.buffer_bytes);
  pcap_set_timeout(pcap, 100);  // ms; bounds batching when immediate mode is off
  pcap_set_tstamp_precision(pcap, PCAP_TSTAMP_PRECISION_NANO);
  const int rc = pcap_activate(pcap);
  if (rc < 0) {
    std::string why = pcap_statustostr(rc);
    const std::string detail = pcap_geterr(pcap);
    if (!detail.empty()) why += " (" + detail + ")";
    // The one privilege capture needs; say so (systemd: docs/daemon.md's capture drop-in).
    if (rc == PCAP_ERROR_PERM_DENIED) why += "; capturing needs CAP_NET_RAW";
    if (detail.find("Address family not supported") != std::string::npos)
      why += "; capturing needs AF_PACKET sockets (and CAP_NET_RAW)";
    fail(why);
  }
  const int dlt = pcap_datalink(pcap);
  if (!is_supported_link_type(dlt)) fail("unsupported link type " + std::to_string(dlt));
  bpf_program program{};
  if (pcap_compile(pcap, &program, filter_.c_str(), 1, PCAP_NETMASK_UNKNOWN) != 0) {
    fail("bad filter '" + filter_ + "': " + pcap_geterr(pcap));
  }
  const int set = pcap_setfilter(pcap, &program);
  pcap_freecode(&program);
  if (set != 0) fail("cannot set filter '" + filter_ + "': " + pcap_geterr(pcap));
  if (pcap_setnonblock(pcap, 1, errbuf) != 0) fail(errbuf);
  fd_ = pcap_get_selectable_fd(pcap);
  pcap_ = pcap;
  link_type_ = dlt;
}

LiveSource::~LiveSource() {
  if (pcap_ != nullptr) pcap_close(as_pcap(pcap_));
}

ReadStatus LiveSource::next(RawPacket& out, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    pcap_pkthdr* header = nullptr;
    const u_char* data = nullptr;
    const int rc = pcap_next_ex(as_pcap(pcap_), &header, &data);
    if (rc == 1) {
      UdpView udp;
      FrameStatus status;
      // The filter already selected these; checked again for frames it cannot see into.
      if (!accept_udp_frame(static_cast<LinkType>(link_type_), {data, header->caplen},
                            {options_.data_port, options_.position_port, options_.sensor_ipv4}, udp,
                            stats_, status))
        continue;
      out.payload = udp.payload;
      out.receive_time_ns = static_cast<int64_t>(header->ts.tv_sec) * 1'000'000'000 +
                            static_cast<int64_t>(header->ts.tv_usec);  // ns precision
      out.source_ipv4 = udp.source_ipv4;
      out.destination_port = udp.destination_port;
      ++stats_.packets;
      stats_.bytes += out.payload.size();
      return ReadStatus::kPacket;
    }
    if (rc == PCAP_ERROR_BREAK) return ReadStatus::kEnd;
    if (rc < 0) {
      ++stats_.errors;
      return ReadStatus::kError;
    }
    // Nothing buffered: wait on the descriptor for what is left of the timeout.
    const auto left =
        std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return ReadStatus::kTimeout;
    pollfd fd{fd_, POLLIN, 0};
    const int ready = ::poll(&fd, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno != EINTR) {
      ++stats_.errors;
      return ReadStatus::kError;
    }
    if (ready == 0) return ReadStatus::kTimeout;
  }
}

SourceStats LiveSource::stats() const {
  SourceStats s = stats_;
  pcap_stat ps{};
  if (pcap_stats(as_pcap(pcap_), &ps) == 0) s.kernel_drops = uint64_t{ps.ps_drop} + ps.ps_ifdrop;
  return s;
}

}  // namespace lidartag::driver
