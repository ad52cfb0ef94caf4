// Writes UDP payloads as a classic pcap file (link type Ethernet, microsecond timestamps, this
// machine's byte order, as libpcap writes it), each wrapped in a real Ethernet II + IPv4 + UDP
// frame with valid checksums, so the file reads like a capture of a sensor (Wireshark, tcpdump,
// PcapSource). Output is deterministic: the same calls give the same bytes (the IPv4
// identification is a per-file counter, MAC addresses are fixed).
//
// Records are collected in the writer's own buffer and written with write(2) when it is full, on
// flush() and on close(). libpcap's pcap_dump() is not used: it returns nothing and writes through
// stdio, so a full disk shows only at some later flush, after an unknown number of records were
// lost. Here a failed or short write is known at once, the file is cut back to its last whole
// record (it stays a valid capture), records() then says exactly how many it holds, and the
// writer stops: error() says why.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::driver {

enum class PcapWriteStatus : uint8_t {
  kOk,          // the record is buffered (or in the file)
  kClosed,      // the writer was closed
  kTooLarge,    // the payload exceeds PcapWriter::kMaxPayload
  kWriteError,  // writing failed (now or before): see error(); nothing more is written
};

class PcapWriter {
 public:
  static constexpr uint32_t kDefaultSourceIpv4 = 0xC0A801C9;  // 192.168.1.201, a Velodyne default
  static constexpr uint32_t kBroadcastIpv4 = 0xFFFFFFFF;
  static constexpr size_t kMaxPayload = 65507;  // largest UDP payload in one IPv4 datagram
  // Records are written in blocks of up to this many bytes (about 200 VLP-32C packets).
  static constexpr size_t kBufferBytes = 256 * 1024;

  // Creates (truncates) `path` and writes the file header. Throws IoError with the path and the
  // reason when the file cannot be created or written, or is a FIFO that nobody reads (opening
  // it never blocks). With `follow_links` false a symbolic link is refused (a daemon running as
  // root must not overwrite whatever a link points to).
  explicit PcapWriter(const std::string& path, bool follow_links = true);
  ~PcapWriter();
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;

  // Appends one frame carrying `payload` from src_ipv4:src_port to dst_ipv4:dst_port (addresses in
  // host byte order; src_port 0 = same as dst_port, as Velodyne sensors do). `time_ns` (ns since
  // the epoch) becomes the record timestamp, truncated to microseconds. For per-packet paths:
  // never throws, never allocates.
  [[nodiscard]] PcapWriteStatus append_udp(std::span<const uint8_t> payload, int64_t time_ns,
                                           uint16_t dst_port,
                                           uint32_t src_ipv4 = kDefaultSourceIpv4,
                                           uint32_t dst_ipv4 = kBroadcastIpv4,
                                           uint16_t src_port = 0) noexcept;
  // append_udp for tools that write a whole file: throws IoError unless the record was taken.
  void write_udp(std::span<const uint8_t> payload, int64_t time_ns, uint16_t dst_port,
                 uint32_t src_ipv4 = kDefaultSourceIpv4, uint32_t dst_ipv4 = kBroadcastIpv4,
                 uint16_t src_port = 0);

  // Writes the buffered records to the file; false when that (or an earlier write) failed.
  [[nodiscard]] bool flush() noexcept;
  // Flushes and closes the file; throws IoError if not every record taken is in it. Idempotent.
  void close();

  bool is_open() const { return fd_ >= 0; }
  bool failed() const { return !error_.empty(); }
  // "cannot write 'PATH': REASON" after a write error; empty while all went well.
  const std::string& error() const { return error_; }
  // Records taken and not lost: in the file or buffered. After a write error, and after close(),
  // exactly the records in the file.
  uint64_t records() const { return in_file_ + buffered_; }
  const std::string& path() const { return path_; }

 private:
  void write_failed(size_t written, int error) noexcept;

  std::string path_;
  int fd_ = -1;
  std::vector<uint8_t> buffer_;  // whole records, allocated once
  size_t used_ = 0;
  uint64_t buffered_ = 0;    // records in buffer_
  uint64_t in_file_ = 0;     // records in the file
  uint64_t file_bytes_ = 0;  // bytes in the file (header and whole records)
  uint16_t ip_id_ = 0;
  std::string error_;
};

}  // namespace lidartag::driver
