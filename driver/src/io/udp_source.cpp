#include "lidartag/driver/io/udp_source.hpp"

#include <arpa/inet.h>
#include <linux/filter.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>

// Asio's scheduler trips -Wnull-dereference when inlined at -O2 (a false positive inside Boost).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/multicast.hpp>
#include <boost/asio/ip/udp.hpp>
#pragma GCC diagnostic pop
#include <cerrno>
#include <cstring>
#include <ctime>

namespace lidartag::driver {

namespace asio = boost::asio;
using asio::ip::udp;

namespace {

constexpr size_t kMaxDatagram = 65536;  // larger than any IPv4 UDP payload

int64_t host_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool set_int_option(int fd, int level, int name, int value) {
  return ::setsockopt(fd, level, name, &value, sizeof(value)) == 0;
}

// Steers each datagram of a SO_REUSEPORT group to the socket of its sender: the group's sockets
// are in the order they were bound (the order of `senders`); the program returns the index of
// the datagram's IPv4 source address among them, and an index past the group (a sender not
// listed) leaves the choice to the kernel's hash.
bool attach_sender_steering(int fd, const std::vector<uint32_t>& senders) {
  if (senders.empty() || senders.size() > 64) return false;
  std::vector<sock_filter> code;
  // A = the IPv4 source address (the network header, whatever offset the UDP payload is at).
  code.push_back(BPF_STMT(BPF_LD | BPF_W | BPF_ABS, static_cast<uint32_t>(SKF_NET_OFF + 12)));
  const auto n = senders.size();
  for (size_t i = 0; i < n; ++i) {
    // Compare i sits at 1 + i, "return i" at n + 2 + i: equal jumps n ahead of the next one.
    code.push_back(BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, senders[i], static_cast<uint8_t>(n), 0));
  }
  code.push_back(BPF_STMT(BPF_RET | BPF_K, 0xFFFFFFFFu));  // not listed: the kernel's hash
  for (size_t i = 0; i < n; ++i) {
    code.push_back(BPF_STMT(BPF_RET | BPF_K, static_cast<uint32_t>(i)));
  }
  sock_fprog program{static_cast<unsigned short>(code.size()), code.data()};
  return ::setsockopt(fd, SOL_SOCKET, SO_ATTACH_REUSEPORT_CBPF, &program, sizeof(program)) == 0;
}

}  // namespace

struct UdpSource::Socket {
  Socket(asio::io_context& io, uint16_t requested) : socket(io), port(requested) {}
  udp::socket socket;
  uint16_t port;
  uint32_t drops = 0;  // the kernel's cumulative SO_RXQ_OVFL count
  std::array<uint8_t, kMaxDatagram> buffer{};
};

struct UdpSource::Impl {
  asio::io_context io;
  std::vector<std::unique_ptr<Socket>> sockets;
};

UdpSource::UdpSource(UdpSourceOptions options)
    : impl_(std::make_unique<Impl>()), options_(std::move(options)) {
  boost::system::error_code ec;
  const asio::ip::address_v4 address = asio::ip::make_address_v4(options_.bind_address, ec);
  if (ec) throw IoError("invalid bind address '" + options_.bind_address + "': " + ec.message());

  const bool multicast = address.is_multicast();
  auto open = [&](uint16_t port) -> Socket& {
    auto socket = std::make_unique<Socket>(impl_->io, port);
    udp::socket& s = socket->socket;
    const std::string where = options_.bind_address + ":" + std::to_string(port);
    if (s.open(udp::v4(), ec))
      throw IoError("cannot open UDP socket for " + where + ": " + ec.message());
    if (options_.reuse_address || multicast) {
      s.set_option(asio::socket_base::reuse_address(true), ec);
      if (ec) throw IoError("cannot share UDP " + where + ": " + ec.message());
    }
    const int fd = s.native_handle();
    const bool steer = options_.reuse_address && !multicast && !options_.steer_senders.empty();
    if (steer && !set_int_option(fd, SOL_SOCKET, SO_REUSEPORT, 1)) {
      throw IoError("cannot share UDP " + where +
                    " by sender (SO_REUSEPORT): " + std::strerror(errno));
    }
    // Ask for the buffer; when capped by rmem_max, try to force it (needs CAP_NET_ADMIN).
    s.set_option(asio::socket_base::receive_buffer_size(options_.receive_buffer_bytes), ec);
    asio::socket_base::receive_buffer_size granted;
    s.get_option(granted, ec);
    if (granted.value() < options_.receive_buffer_bytes) {
      set_int_option(fd, SOL_SOCKET, SO_RCVBUFFORCE, options_.receive_buffer_bytes);
      s.get_option(granted, ec);
    }
    granted_buffer_ =
        granted_buffer_ == 0 ? granted.value() : std::min(granted_buffer_, granted.value());
    timestamps_active_ =
        options_.kernel_timestamps && set_int_option(fd, SOL_SOCKET, SO_TIMESTAMPNS, 1);
    set_int_option(fd, SOL_SOCKET, SO_RXQ_OVFL, 1);
    if (s.bind(udp::endpoint(address, port), ec)) {
      std::string why = ec.message();
      if (ec == boost::system::errc::address_in_use) {
        why += options_.reuse_address || multicast
                   ? " (another program has it and does not share it)"
                   : " (another program receives on this port, e.g. a second lidartagd or a "
                     "sensor driver; it is bound exclusively unless every user shares it)";
      }
      throw IoError("cannot bind UDP " + where + ": " + why);
    }
    if (steer && !attach_sender_steering(fd, options_.steer_senders)) {
      throw IoError("cannot steer UDP " + where +
                    " by sender (SO_ATTACH_REUSEPORT_CBPF): " + std::strerror(errno));
    }
    if (multicast) {
      s.set_option(asio::ip::multicast::join_group(address), ec);
      if (ec) {
        throw IoError("cannot join the multicast group " + options_.bind_address + ": " +
                      ec.message() + " (is there a route for it? e.g. 'ip route add " +
                      "224.0.0.0/4 dev eth0')");
      }
    }
    socket->port = s.local_endpoint(ec).port();
    s.non_blocking(true, ec);
    impl_->sockets.push_back(std::move(socket));
    return *impl_->sockets.back();
  };
  data_port_ = open(options_.data_port).port;
  if (options_.open_position_port) position_port_ = open(options_.position_port).port;
}

UdpSource::~UdpSource() = default;

ReadStatus UdpSource::receive(Socket& socket, RawPacket& out) {
  sockaddr_in from{};
  iovec iov{socket.buffer.data(), socket.buffer.size()};
  alignas(cmsghdr) std::array<uint8_t, CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(uint32_t))>
      control{};
  msghdr msg{};
  msg.msg_name = &from;
  msg.msg_namelen = sizeof(from);
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control.data();
  msg.msg_controllen = control.size();
  const ssize_t n = ::recvmsg(socket.socket.native_handle(), &msg, MSG_DONTWAIT);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return ReadStatus::kTimeout;
    ++stats_.errors;
    return ReadStatus::kError;
  }
  bool stamped = false;
  int64_t stamp_ns = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof(ts));
      stamp_ns = static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      stamped = true;
    } else if (c->cmsg_type == SO_RXQ_OVFL) {
      std::memcpy(&socket.drops, CMSG_DATA(c), sizeof(socket.drops));
    }
  }
  if ((msg.msg_flags & MSG_TRUNC) != 0) {
    ++stats_.truncated;
    return ReadStatus::kTimeout;
  }
  const uint32_t source = ntohl(from.sin_addr.s_addr);
  if (options_.sensor_ipv4 && source != *options_.sensor_ipv4) {
    ++stats_.foreign_source;
    return ReadStatus::kTimeout;
  }
  if (!stamped) {
    stamp_ns = host_now_ns();
    ++host_clock_stamps_;
  }
  out.payload = std::span<const uint8_t>(socket.buffer.data(), static_cast<size_t>(n));
  out.receive_time_ns = stamp_ns;
  out.source_ipv4 = source;
  out.destination_port = socket.port;
  ++stats_.packets;
  stats_.bytes += static_cast<uint64_t>(n);
  return ReadStatus::kPacket;
}

ReadStatus UdpSource::next(RawPacket& out, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::array<pollfd, 2> fds{};
  const size_t count = impl_->sockets.size();
  for (size_t i = 0; i < count; ++i) {
    fds[i].fd = impl_->sockets[i]->socket.native_handle();
    fds[i].events = POLLIN;
  }
  for (;;) {
    // Try every socket first, starting after the one served last, so neither port starves.
    for (size_t k = 0; k < count; ++k) {
      const size_t i = (next_socket_ + k) % count;
      const ReadStatus status = receive(*impl_->sockets[i], out);
      if (status == ReadStatus::kTimeout) continue;  // nothing there, or ignored
      next_socket_ = (i + 1) % count;
      return status;
    }
    const auto left =
        std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return ReadStatus::kTimeout;
    const int ready =
        ::poll(fds.data(), static_cast<nfds_t>(count), static_cast<int>(left.count()));
    if (ready < 0 && errno != EINTR) {
      ++stats_.errors;
      return ReadStatus::kError;
    }
    if (ready == 0) return ReadStatus::kTimeout;
  }
}

SourceStats UdpSource::stats() const {
  SourceStats s = stats_;
  for (const auto& socket : impl_->sockets) s.kernel_drops += socket->drops;
  return s;
}

}  // namespace lidartag::driver
