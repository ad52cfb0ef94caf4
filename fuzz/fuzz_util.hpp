// Shared pieces of the fuzz targets: an in-memory file with a path (the readers open paths), a
// packet source over a byte string, and a check that stops the fuzzer with a message.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <string_view>

#include "lidartag/driver/packet_source.hpp"

namespace lidartag::fuzz {

// A broken invariant: libFuzzer keeps the input as a crash.
[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz invariant violated: %s\n", what.c_str());
  std::abort();
}
inline void check(bool ok, const std::string& what) {
  if (!ok) fail(what);
}

// An error message fit for one log line: no control characters (newlines above all).
inline bool one_line(std::string_view text) {
  for (const char c : text)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) return false;
  return true;
}

// An anonymous memory file (memfd) opened by path through /proc/self/fd: the readers under test
// take file names, and nothing touches the disk. One per process, rewritten for every input.
class MemFile {
 public:
  MemFile() : fd_(memfd_create("lidartag-fuzz", MFD_CLOEXEC)) {
    check(fd_ >= 0, "memfd_create failed");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemFile() { close(fd_); }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;

  const std::string& write(std::span<const uint8_t> bytes) {
    check(ftruncate(fd_, 0) == 0, "ftruncate failed");
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n =
          pwrite(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(done));
      check(n > 0, "pwrite failed");
      done += static_cast<size_t>(n);
    }
    return path_;
  }
  const std::string& path() const { return path_; }

 private:
  int fd_;
  std::string path_;
};

// A packet stream as records, each: kind (1 byte: bit 0 set = position port, else data port;
// bit 1 = from a second sender address), receive-time step (4 bytes, little-endian,
// microseconds after the previous record), length (2 bytes, little-endian; cut to what is left),
// payload. make_seeds writes real captures in this form.
inline constexpr size_t kRecordHeader = 7;

class RecordSource final : public driver::PacketSource {
 public:
  explicit RecordSource(std::span<const uint8_t> data, int64_t start_ns = 1'700'000'000'000'000'000)
      : data_(data), time_ns_(start_ns) {}

  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds) override {
    if (data_.size() < kRecordHeader) return driver::ReadStatus::kEnd;
    const uint8_t kind = data_[0];
    // Little-endian, as the record form is written (the fuzzers of every layer share it: no
    // vendor's byte readers here).
    const uint32_t step_us = uint32_t{data_[1]} | uint32_t{data_[2]} << 8 |
                             uint32_t{data_[3]} << 16 | uint32_t{data_[4]} << 24;
    const size_t length =
        std::min<size_t>(size_t{data_[5]} | size_t{data_[6]} << 8, data_.size() - kRecordHeader);
    out.payload = data_.subspan(kRecordHeader, length);
    time_ns_ += int64_t{step_us} * 1000;
    out.receive_time_ns = time_ns_;
    out.source_ipv4 = (kind & 2) != 0 ? 0xC0A8010Bu : 0xC0A8010Au;  // 192.168.1.11 / .10
    out.destination_port =
        (kind & 1) != 0 ? driver::kDefaultPositionPort : driver::kDefaultDataPort;
    data_ = data_.subspan(kRecordHeader + length);
    ++stats_.packets;
    stats_.bytes += length;
    return driver::ReadStatus::kPacket;
  }
  driver::SourceStats stats() const override { return stats_; }

 private:
  std::span<const uint8_t> data_;
  int64_t time_ns_;
  driver::SourceStats stats_{};
};

}  // namespace lidartag::fuzz
