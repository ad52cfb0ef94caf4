#include "lidartag/daemon/lcm_log_source.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

#include "lidartag/driver/io/errors.hpp"

namespace lidartag::daemon {

using driver::ReadStatus;

namespace {

int32_t read_be32(const uint8_t* p) {
  return static_cast<int32_t>((static_cast<uint32_t>(p[0]) << 24) |
                              (static_cast<uint32_t>(p[1]) << 16) |
                              (static_cast<uint32_t>(p[2]) << 8) | static_cast<uint32_t>(p[3]));
}

// Checks the lengths inside an encoded raw_packet_t before decode() trusts them: a corrupt
// `nbytes` would otherwise make it allocate up to 2 GB before failing. Layout: hash (8), utime
// (8), receive_time_ns (8), sensor (int32 length with the NUL, bytes), source_ipv4 (4), port (4),
// nbytes (4), data.
bool plausible_raw_packet(const uint8_t* data, size_t size) {
  size_t offset = 24;
  if (size < offset + 4) return false;
  const int32_t string_size = read_be32(data + offset);
  offset += 4;
  if (string_size <= 0 || static_cast<size_t>(string_size) > size - offset) return false;
  offset += static_cast<size_t>(string_size);
  if (size < offset + 12) return false;
  const int32_t nbytes = read_be32(data + offset + 8);
  return nbytes >= 0 && static_cast<size_t>(nbytes) == size - offset - 12;
}

// The sync word that starts every LCM log event.
constexpr uint32_t kEventMagic = 0xEDA1DA01U;

}  // namespace

LcmLogSource::LcmLogSource(const std::string& path, LcmLogSourceOptions options)
    : path_(path),
      options_(std::move(options)),
      log_(std::make_unique<lcm::LogFile>(path, "r")),
      schedule_(options_.rate > 0 ? options_.rate : 1.0) {
  if (!log_->good()) throw driver::IoError("cannot open LCM log '" + path + "'");
  std::error_code ec;
  file_size_ = static_cast<long>(std::filesystem::file_size(path, ec));
  if (options_.rate < 0) throw driver::IoError("LCM log replay rate must be >= 0");
}

LcmLogSource::~LcmLogSource() = default;

bool LcmLogSource::next_event_fits() {
  // LCM allocates the data length an event header claims (calloc, up to 2 GB for a corrupt header)
  // before it reads the data and finds the file too short. Its header is looked at first, as LCM
  // finds it (after the sync word), and the file position is then put back for LCM.
  FILE* f = log_->getFilePtr();
  const long start = std::ftell(f);
  if (start < 0) return true;
  uint32_t magic = 0;
  int c = 0;
  do {
    c = std::fgetc(f);
    magic = (magic << 8) | static_cast<uint32_t>(c & 0xff);
  } while (c != EOF && magic != kEventMagic);
  bool fits = true;
  uint8_t header[24];  // event number (8), timestamp (8), channel length (4), data length (4)
  if (c != EOF && std::fread(header, 1, sizeof header, f) == sizeof header) {
    const int32_t channel = read_be32(header + 16), data = read_be32(header + 20);
    const long end = std::ftell(f) + channel + data;  // LCM refuses other lengths itself
    if (channel > 0 && channel < 1000 && data >= 0 && end > file_size_) {
      struct stat st {};
      if (::fstat(::fileno(f), &st) == 0) file_size_ = static_cast<long>(st.st_size);  // growing
      fits = end <= file_size_;
    }
  }
  std::clearerr(f);
  return std::fseek(f, start, SEEK_SET) == 0 && fits;
}

bool LcmLogSource::read_one() {
  for (;;) {
    const lcm::LogEvent* event = next_event_fits() ? log_->readNextEvent() : nullptr;
    if (event == nullptr) {
      // LCM stops at a cut or corrupt event header as at the end of the file: bytes left past
      // the last whole event mean the log was truncated.
      if (end_of_events_ < file_size_) ++stats_.truncated;
      return false;
    }
    end_of_events_ = std::ftell(log_->getFilePtr());
    ++events_;
    if (event->channel != options_.channel) {
      ++stats_.ignored;
      continue;
    }
    int used = -1;
    const auto* bytes = static_cast<const uint8_t*>(event->data);
    const auto size = static_cast<size_t>(std::max<int32_t>(event->datalen, 0));
    if (plausible_raw_packet(bytes, size)) {
      try {
        used = message_.decode(bytes, 0, static_cast<int>(size));
      } catch (const std::exception&) {
        used = -1;  // LCM's decode throws std::length_error on some corrupt lengths
      }
    }
    // receive_time_ns is any int64 in a corrupt message: out of range, it would overflow the
    // time arithmetic of the loop shift, the batcher and the clock.
    if (used < 0 || message_.nbytes < 0 ||
        static_cast<size_t>(message_.nbytes) != message_.data.size() || message_.port <= 0 ||
        message_.port > 65535 || message_.receive_time_ns < 0 ||
        message_.receive_time_ns >= driver::kMaxReceiveTimeNs) {
      ++stats_.malformed;
      continue;
    }
    const int64_t t = message_.receive_time_ns;
    if (!have_first_) {
      have_first_ = true;
      first_ns_ = t;
    } else if (t > last_ns_) {
      last_interval_ns_ = t - last_ns_;
    }
    last_ns_ = t;
    time_ns_ = t + shift_ns_;
    return true;
  }
}

ReadStatus LcmLogSource::next(driver::RawPacket& out, std::chrono::milliseconds timeout) {
  if (!pending_) {
    if (!read_one()) {
      if (!options_.loop || !have_first_) return ReadStatus::kEnd;
      // Next pass: reopen, and shift times so that they keep growing (below 2 kMaxReceiveTimeNs:
      // the loop ends after ~136 years of replay rather than overflow).
      const int64_t step = last_ns_ - first_ns_ + last_interval_ns_;
      if (shift_ns_ > driver::kMaxReceiveTimeNs - step) return ReadStatus::kEnd;
      shift_ns_ += step;
      have_first_ = false;
      log_ = std::make_unique<lcm::LogFile>(path_, "r");
      end_of_events_ = 0;
      if (!log_->good()) {
        ++stats_.errors;
        return ReadStatus::kError;
      }
      if (!read_one()) return ReadStatus::kEnd;
    }
    pending_ = true;
  }
  if (options_.rate > 0 && !schedule_.wait(time_ns_, timeout)) return ReadStatus::kTimeout;
  pending_ = false;
  out.payload = std::span<const uint8_t>(message_.data.data(), message_.data.size());
  out.receive_time_ns = time_ns_;
  out.source_ipv4 = static_cast<uint32_t>(message_.source_ipv4);
  out.destination_port = static_cast<uint16_t>(message_.port);
  ++stats_.packets;
  stats_.bytes += message_.data.size();
  return ReadStatus::kPacket;
}

}  // namespace lidartag::daemon
