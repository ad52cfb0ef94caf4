#include "lidartag/driver/io/pcap_writer.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "net_headers.hpp"

namespace lidartag::driver {
namespace {

// Fixed addresses keep the output deterministic: 60:76:88 is Velodyne's OUI.
constexpr uint8_t kSourceMac[6] = {0x60, 0x76, 0x88, 0x00, 0x00, 0x01};
constexpr uint8_t kBroadcastMac[6] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
constexpr uint32_t kSnapLength = 65535;
constexpr uint32_t kLinkTypeEthernet = 1;
constexpr size_t kFileHeader = 24;
constexpr size_t kRecordHeader = 16;  // seconds, microseconds, captured length, length

// pcap headers are in the writer's byte order (readers tell it from the magic number).
void put_u32(uint8_t* p, uint32_t v) {
  std::memcpy(p, &v, sizeof(v));
}
void put_u16(uint8_t* p, uint16_t v) {
  std::memcpy(p, &v, sizeof(v));
}
uint32_t get_u32(const uint8_t* p) {
  uint32_t v = 0;
  std::memcpy(&v, p, sizeof(v));
  return v;
}

// write(2) until all is written; the bytes written before a failure in `done`.
bool write_all(int fd, const uint8_t* data, size_t size, size_t& done, int& error) {
  done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : EIO;
      return false;
    }
    done += static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

PcapWriter::PcapWriter(const std::string& path, bool follow_links) : path_(path) {
  const int flags =
      O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NONBLOCK | (follow_links ? 0 : O_NOFOLLOW);
  fd_ = ::open(path.c_str(), flags, 0666);
  if (fd_ < 0) {
    const int error = errno;
    throw IoError("cannot create '" + path + "': " +
                  (error == ELOOP && !follow_links ? "it is a symbolic link (not followed)"
                   : error == ENXIO                ? "it is a FIFO that nobody reads"
                                                   : std::strerror(error)));
  }
  // Blocking writes from here on (O_NONBLOCK only kept open() from waiting for a FIFO's reader).
  ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_NONBLOCK);
  uint8_t header[kFileHeader] = {};
  put_u32(header, 0xA1B2C3D4);  // microsecond timestamps
  put_u16(header + 4, 2);       // version 2.4
  put_u16(header + 6, 4);
  put_u32(header + 16, kSnapLength);
  put_u32(header + 20, kLinkTypeEthernet);
  size_t done = 0;
  int error = 0;
  if (!write_all(fd_, header, sizeof(header), done, error)) {
    ::close(fd_);
    fd_ = -1;
    throw IoError("cannot write '" + path + "': " + std::strerror(error));
  }
  file_bytes_ = sizeof(header);
  buffer_.assign(kBufferBytes, 0);
}

PcapWriter::~PcapWriter() {
  try {
    close();
  } catch (const IoError&) {
    // Destruction cannot report: callers that care call close() (or check error()) first.
  }
}

void PcapWriter::write_udp(std::span<const uint8_t> payload, int64_t time_ns, uint16_t dst_port,
                           uint32_t src_ipv4, uint32_t dst_ipv4, uint16_t src_port) {
  switch (append_udp(payload, time_ns, dst_port, src_ipv4, dst_ipv4, src_port)) {
    case PcapWriteStatus::kOk:
      return;
    case PcapWriteStatus::kClosed:
      throw IoError("write to closed pcap file '" + path_ + "'");
    case PcapWriteStatus::kTooLarge:
      throw IoError("UDP payload of " + std::to_string(payload.size()) + " bytes too large for '" +
                    path_ + "'");
    case PcapWriteStatus::kWriteError:
      throw IoError(error_);
  }
}

PcapWriteStatus PcapWriter::append_udp(std::span<const uint8_t> payload, int64_t time_ns,
                                       uint16_t dst_port, uint32_t src_ipv4, uint32_t dst_ipv4,
                                       uint16_t src_port) noexcept {
  if (failed()) return PcapWriteStatus::kWriteError;
  if (fd_ < 0) return PcapWriteStatus::kClosed;
  if (payload.size() > kMaxPayload) return PcapWriteStatus::kTooLarge;
  if (src_port == 0) src_port = dst_port;
  const size_t udp_length = net::kUdpHeader + payload.size();
  const size_t ip_length = net::kIpv4MinHeader + udp_length;
  const size_t frame_length = net::kEthernetHeader + ip_length;
  if (used_ + kRecordHeader + frame_length > buffer_.size() && !flush()) {
    return PcapWriteStatus::kWriteError;
  }
  uint8_t* record = buffer_.data() + used_;
  uint8_t* eth = record + kRecordHeader;
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
  put_u32(record, static_cast<uint32_t>(sec));
  put_u32(record + 4, static_cast<uint32_t>(usec_part));
  put_u32(record + 8, static_cast<uint32_t>(frame_length));
  put_u32(record + 12, static_cast<uint32_t>(frame_length));
  used_ += kRecordHeader + frame_length;
  ++buffered_;
  return PcapWriteStatus::kOk;
}

bool PcapWriter::flush() noexcept {
  if (failed()) return false;
  if (fd_ < 0 || used_ == 0) return true;
  size_t done = 0;
  int error = 0;
  if (!write_all(fd_, buffer_.data(), used_, done, error)) {
    write_failed(done, error);
    return false;
  }
  file_bytes_ += used_;
  in_file_ += buffered_;
  used_ = 0;
  buffered_ = 0;
  return true;
}

void PcapWriter::write_failed(size_t written, int error) noexcept {
  // The whole records among the bytes that reached the file stay; a torn one is cut off.
  size_t whole_bytes = 0;
  uint64_t whole = 0;
  while (whole_bytes + kRecordHeader <= used_) {
    const size_t length = kRecordHeader + get_u32(buffer_.data() + whole_bytes + 8);
    if (whole_bytes + length > written) break;
    whole_bytes += length;
    ++whole;
  }
  error_ = "cannot write '" + path_ + "': " + std::strerror(error);
  if (written > whole_bytes &&
      ::ftruncate(fd_, static_cast<off_t>(file_bytes_ + whole_bytes)) != 0) {
    error_ += std::string(" (and its last record, cut short, could not be removed: ") +
              std::strerror(errno) + ")";
  }
  file_bytes_ += whole_bytes;
  in_file_ += whole;
  used_ = 0;
  buffered_ = 0;
}

void PcapWriter::close() {
  if (fd_ < 0) return;
  (void)flush();  // a failure is in error_
  if (::close(fd_) != 0 && !failed()) {
    error_ = "cannot write '" + path_ + "': " + std::strerror(errno);
  }
  fd_ = -1;
  if (failed()) throw IoError(error_);
}

}  // namespace lidartag::driver
