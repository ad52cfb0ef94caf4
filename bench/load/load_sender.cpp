#include "load_sender.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/velodyne/packet.hpp"

namespace lidartag::load {

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
namespace v = lidartag::velodyne;

constexpr uint32_t kHourUs = 3'600'000'000u;
constexpr size_t kMaxDatagram = 65507;  // largest UDP payload over IPv4

double azimuth_of(const std::vector<uint8_t>& payload) {
  return v::read_u16(payload.data() + 2) / 100.0;  // block 0
}

uint32_t clock_of(const Capture::Packet& p) {
  return v::read_u32(p.payload.data() +
                     (p.position ? v::kPositionTimestampOffset : v::kTimestampOffset));
}

// Packets whose first column is the first after the 180 degree cut.
std::vector<size_t> cut_crossings(const std::vector<Capture::Packet>& packets) {
  std::vector<size_t> crossings;
  double previous = -1;
  for (size_t i = 0; i < packets.size(); ++i) {
    if (packets[i].position) continue;
    const double az = azimuth_of(packets[i].payload);
    if (previous >= 0) {
      const double step = std::fmod(az - previous + 360.0, 360.0);
      const double to_cut = std::fmod(180.0 - previous + 360.0, 360.0);
      if (step < 90.0 && to_cut > 0.0 && to_cut <= step) crossings.push_back(i);
    }
    previous = az;
  }
  return crossings;
}

// The kernel's range of ports for sockets bound to port 0.
std::pair<unsigned, unsigned> ephemeral_ports() {
  std::ifstream in("/proc/sys/net/ipv4/ip_local_port_range");
  unsigned low = 32768, high = 60999;  // Linux's default
  if (unsigned l = 0, h = 0; in >> l >> h && l <= h) low = l, high = h;
  return {low, high};
}

sockaddr_in address(const std::string& ip, uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  if (inet_pton(AF_INET, ip.c_str(), &a.sin_addr) != 1)
    throw std::runtime_error("not an IPv4 address: " + ip);
  return a;
}

}  // namespace

Capture load_capture(const std::string& path, uint16_t data_port, uint16_t position_port) {
  lidartag::driver::PcapSourceOptions o;
  o.data_port = data_port;
  o.position_port = position_port;
  lidartag::driver::PcapSource source(path, o);
  std::vector<Capture::Packet> all;
  lidartag::driver::RawPacket p;
  while (source.next(p, std::chrono::milliseconds(0)) == lidartag::driver::ReadStatus::kPacket) {
    const bool position = p.destination_port == position_port;
    if (!position && p.payload.size() != v::kDataPacketSize) continue;
    if (position && p.payload.size() != v::kPositionPacketSize) continue;
    Capture::Packet& q = all.emplace_back();
    q.payload.assign(p.payload.begin(), p.payload.end());
    q.time_ns = p.receive_time_ns;
    q.position = position;
  }
  const std::vector<size_t> cuts = cut_crossings(all);
  Capture c;
  size_t first = 0, end = all.size();
  if (cuts.size() >= 2) {
    first = cuts.front(), end = cuts.back();
    // A pass of whole packets is whole rotations only to within a packet: end it where the packet
    // that would follow it is closest in azimuth to its first packet (the packet before the last
    // crossing may be closer than the crossing packet itself).
    const double az0 = azimuth_of(all[first].payload);
    const auto off_by = [&](size_t k) {
      return std::abs(std::remainder(azimuth_of(all[k].payload) - az0, 360.0));
    };
    size_t before = end - 1;
    while (before > first && all[before].position) --before;
    if (before > first && off_by(before) < off_by(end)) end = before;
  }
  c.packets.reserve(end - first);
  for (size_t k = first; k < end; ++k) c.packets.push_back(std::move(all[k]));
  size_t data = 0;
  for (const auto& q : c.packets) data += q.position ? 0 : 1;
  if (data < 2) throw std::runtime_error(path + ": fewer than two data packets");
  // One pass lasts up to the packet that would follow it (the crossing that ends the last
  // rotation), in capture time and on the sensor's clock.
  if (end < all.size()) {
    // The pass's first packet is not exactly at the azimuth of the one that would follow the pass
    // (both only straddle the cut): the next pass starts when the sensor would have reached the
    // first packet's azimuth again, else each seam steps the azimuth back by a fraction of a
    // degree at continuous time, which no sensor does (and the daemon rightly drops as stray).
    const double excess =
        std::remainder(azimuth_of(all[end].payload) - azimuth_of(c.packets.front().payload), 360.0);
    const double turned = 360.0 * static_cast<double>(cuts.size() - 1) + excess;
    const double ns_per_deg =
        static_cast<double>(all[end].time_ns - c.packets.front().time_ns) / turned;
    const auto back_ns = static_cast<int64_t>(std::llround(excess * ns_per_deg));
    c.span_ns = all[end].time_ns - c.packets.front().time_ns - back_ns;
    const int64_t clock_span_us =
        static_cast<int64_t>((clock_of(all[end]) + kHourUs - clock_of(c.packets.front())) %
                             kHourUs) -
        back_ns / 1000;
    c.span_clock_us = static_cast<uint32_t>(clock_span_us);
  } else {
    const int64_t step = (c.packets.back().time_ns - c.packets.front().time_ns) /
                         static_cast<int64_t>(c.packets.size() - 1);
    c.span_ns = c.packets.back().time_ns - c.packets.front().time_ns + step;
    c.span_clock_us = static_cast<uint32_t>(c.span_ns / 1000);
  }
  c.data_rate_hz = static_cast<double>(data) / (static_cast<double>(c.span_ns) * 1e-9);
  return c;
}

SenderCounts send(const Capture& capture, const SenderOptions& o, const std::atomic<bool>& stop) {
  SenderCounts n;
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error("socket failed");
  const sockaddr_in from = address(o.source_address, 0);
  if (bind(fd, reinterpret_cast<const sockaddr*>(&from), sizeof(from)) != 0) {
    close(fd);
    throw std::runtime_error("cannot bind the sender to " + o.source_address);
  }
  const int sndbuf = 4 << 20;
  setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof(sndbuf));
  const sockaddr_in data_to = address(o.destination, o.data_port);
  const sockaddr_in position_to = address(o.destination, o.position_port);

  // Junk for closed ports never goes to an ephemeral port: a sender's own socket (this one, or a
  // second sender's) is bound there, and junk it never reads would fill its buffer (a 10-minute
  // soak hit the sender's port 111 times: 79 receive-buffer errors that nothing sent to the daemon
  // explained).
  const std::pair<unsigned, unsigned> ephemeral = ephemeral_ports();
  std::vector<uint16_t> junk_ports;  // closed ports: not ephemeral, not the sensor's, not LCM's
  for (unsigned p = 1024; p <= 65535; ++p)
    if (p != o.data_port && p != o.position_port && p != 7667 &&
        (p < ephemeral.first || p > ephemeral.second))
      junk_ports.push_back(static_cast<uint16_t>(p));
  if (junk_ports.empty() && o.junk_ratio > 0.0 && o.junk_to_sensor < 1.0)
    throw std::runtime_error("no port above 1023 is outside the kernel's ephemeral range " +
                             std::to_string(ephemeral.first) + "-" +
                             std::to_string(ephemeral.second) + " for junk to closed ports");
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<uint8_t> junk(kMaxDatagram + 4096);
  for (auto& b : junk) b = static_cast<uint8_t>(rng());
  std::vector<uint8_t> buffer, held;
  bool holding = false;

  auto raw_send = [&](const uint8_t* data, size_t size, const sockaddr_in& to) {
    if (sendto(fd, data, size, 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to)) ==
        static_cast<ssize_t>(size)) {
      n.bytes += size;
      return true;
    }
    ++n.send_errors;
    return false;
  };
  // A junk datagram: log-uniform size in [0, 65507] (most small, some huge), random bytes.
  auto send_junk = [&] {
    const double u = uniform(rng);
    size_t size = u < 0.01   ? 0
                  : u > 0.99 ? kMaxDatagram
                             : static_cast<size_t>(std::exp(uniform(rng) * std::log(65507.0)));
    const size_t offset = static_cast<size_t>(rng() % 4096);
    if (uniform(rng) < o.junk_to_sensor) {
      if (size == v::kDataPacketSize) ++size;
      if (raw_send(junk.data() + offset, size, data_to)) ++n.junk_sensor_port;
      return;
    }
    const uint16_t port = junk_ports[rng() % junk_ports.size()];
    if (raw_send(junk.data() + offset, size, address(o.destination, port))) ++n.junk_wrong_port;
  };

  // Junk of the probe's size before the sensor speaks (counted with the junk to the data port).
  std::vector<uint8_t> probe_junk(v::kDataPacketSize, 0);
  for (uint64_t i = 0; i < o.probe_junk; ++i) {
    probe_junk[v::kProductIdOffset] = i == 0 ? 0x22 : 0x00;
    if (raw_send(probe_junk.data(), probe_junk.size(), data_to)) ++n.junk_sensor_port;
  }

  const auto start = Clock::now();
  const auto end =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.seconds));
  auto anchor = start;
  uint64_t loop = 0;
  size_t index = 0;
  bool restarted = false;
  double junk_due = 0;
  uint64_t data_handled = 0;
  const int64_t first_ns = capture.packets.front().time_ns;
  while (!stop.load(std::memory_order_relaxed)) {
    const auto now = Clock::now();
    if (now >= end) break;
    if (o.restart_after_s > 0 && !restarted &&
        now - start >= std::chrono::duration<double>(o.restart_after_s)) {
      // The sensor restarts: silence, then the capture from its start on its original clock.
      restarted = true;
      ++n.restarts;
      std::this_thread::sleep_for(std::chrono::duration<double>(o.restart_silence_s));
      anchor = Clock::now();
      loop = 0;
      index = 0;
      continue;
    }
    const Capture::Packet& p = capture.packets[index];
    if (o.rate > 0) {
      const double offset_s = (static_cast<double>(loop) * static_cast<double>(capture.span_ns) +
                               static_cast<double>(p.time_ns - first_ns)) *
                              1e-9 / o.rate;
      const auto due = anchor + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>(offset_s));
      if (due > now) {
        std::this_thread::sleep_until(std::min(due, end));
        continue;
      }
    }
    buffer = p.payload;
    const size_t at = p.position ? v::kPositionTimestampOffset : v::kTimestampOffset;
    const uint64_t shift = loop * capture.span_clock_us;
    v::write_u32(buffer.data() + at,
                 static_cast<uint32_t>((v::read_u32(buffer.data() + at) + shift) % kHourUs));
    // Faults only between the first data packets and the last quarter second: a loss before
    // the first packet received or after the last cannot be seen by anyone, so exact counts
    // would be impossible.
    const bool impair = data_handled >= 10 && now + 250ms < end;
    if (!p.position) ++data_handled;
    if (p.position) {
      if (raw_send(buffer.data(), buffer.size(), position_to)) ++n.position;
    } else if (impair && uniform(rng) < o.loss) {
      ++n.lost;
    } else if (impair && !holding && uniform(rng) < o.reorder) {
      held = buffer;  // sent after the next data packet
      holding = true;
      ++n.reordered;
    } else {
      if (raw_send(buffer.data(), buffer.size(), data_to)) ++n.data;
      if (impair && uniform(rng) < o.duplicate && raw_send(buffer.data(), buffer.size(), data_to)) {
        ++n.data;
        ++n.duplicated;
      }
      if (holding) {
        if (raw_send(held.data(), held.size(), data_to)) ++n.data;
        holding = false;
      }
    }
    junk_due += o.junk_ratio;
    for (; junk_due >= 1.0; junk_due -= 1.0) send_junk();
    if (++index == capture.packets.size()) {
      index = 0;
      ++loop;
      ++n.loops;
    }
  }
  if (holding && raw_send(held.data(), held.size(), data_to)) ++n.data;
  n.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  close(fd);
  return n;
}

}  // namespace lidartag::load
