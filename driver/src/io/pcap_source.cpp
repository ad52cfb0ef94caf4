#include "lidartag/driver/io/pcap_source.hpp"

#include <pcap/pcap.h>
#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>

namespace lidartag::driver {
namespace {

pcap_t* as_pcap(void* p) {
  return static_cast<pcap_t*>(p);
}

// One microsecond: the smallest step between two passes of a looped file.
constexpr int64_t kMinLoopGapNs = 1000;

// Classic pcap by the file's magic number (either byte order, micro- or nanoseconds), read
// through libpcap's own stream: pcapng starts with 0x0A0D0D0A.
bool is_classic_pcap(pcap_t* pcap) {
  FILE* file = pcap_file(pcap);
  if (file == nullptr) return false;
  const long at = std::ftell(file);
  uint32_t magic = 0;
  const bool read = at >= 0 && std::fseek(file, 0, SEEK_SET) == 0 &&
                    std::fread(&magic, sizeof magic, 1, file) == 1;
  if (at >= 0) std::fseek(file, at, SEEK_SET);
  return read &&
         (magic == 0xa1b2c3d4 || magic == 0xd4c3b2a1 || magic == 0xa1b23c4d || magic == 0x4d3cb2a1);
}

}  // namespace

ReplaySchedule::Clock::time_point ReplaySchedule::due(int64_t capture_ns, Clock::time_point now) {
  if (!anchored_) {
    anchored_ = true;
    first_capture_ns_ = capture_ns;
    anchor_ = now;
  }
  const double offset_ns = static_cast<double>(capture_ns - first_capture_ns_) / rate_;
  return anchor_ + std::chrono::nanoseconds(static_cast<int64_t>(std::llround(offset_ns)));
}

bool ReplaySchedule::wait(int64_t capture_ns, std::chrono::milliseconds timeout) {
  const auto now = Clock::now();
  const auto at = due(capture_ns, now);
  if (at - now > timeout) {
    std::this_thread::sleep_for(timeout);
    return false;
  }
  std::this_thread::sleep_until(at);
  return true;
}

PcapSource::PcapSource(const std::string& path, PcapSourceOptions options)
    : path_(path), options_(options), schedule_(options.rate) {
  if (!(options_.rate > 0.0) || !std::isfinite(options_.rate)) {
    throw IoError("replay rate must be a positive number (got " + std::to_string(options_.rate) +
                  ") for '" + path + "'");
  }
  open();
}

PcapSource::~PcapSource() {
  close();
}

void PcapSource::open() {
  char errbuf[PCAP_ERRBUF_SIZE] = {};
  // Nanosecond precision: libpcap scales microsecond files up, so one code path serves both.
  pcap_t* pcap = nullptr;
  if (path_ == "-") {
    pcap = pcap_open_offline_with_tstamp_precision("-", PCAP_TSTAMP_PRECISION_NANO, errbuf);
  } else {
    // Opened as libpcap would (the same messages), but read in large blocks: stdio's own buffer
    // (4 KiB) made a read() of every three packets.
    FILE* file = std::fopen(path_.c_str(), "rb");
    if (file == nullptr) {
      throw IoError("cannot open capture '" + path_ + "': " + path_ + ": " + std::strerror(errno));
    }
    if (!read_buffer_) read_buffer_ = std::make_unique_for_overwrite<char[]>(kReadBufferBytes);
    std::setvbuf(file, read_buffer_.get(), _IOFBF, kReadBufferBytes);
    pcap = pcap_fopen_offline_with_tstamp_precision(file, PCAP_TSTAMP_PRECISION_NANO, errbuf);
    if (pcap == nullptr) std::fclose(file);  // else pcap_close() closes it
  }
  if (pcap == nullptr) throw IoError("cannot open capture '" + path_ + "': " + errbuf);
  const int dlt = pcap_datalink(pcap);
  if (!is_supported_link_type(dlt)) {
    const char* name = pcap_datalink_val_to_name(dlt);
    pcap_close(pcap);
    throw IoError("capture '" + path_ + "' has unsupported link type " + std::to_string(dlt) +
                  (name != nullptr ? std::string(" (") + name + ")" : std::string()) +
                  "; supported: Ethernet, Linux cooked capture (v1, v2), raw IP");
  }
  pcap_ = pcap;
  link_type_ = dlt;
  classic_ = is_classic_pcap(pcap);
}

void PcapSource::close() {
  if (pcap_ != nullptr) pcap_close(as_pcap(pcap_));
  pcap_ = nullptr;
}

bool PcapSource::read_packet() {
  if (pcap_ == nullptr) return false;
  for (;;) {
    pcap_pkthdr* header = nullptr;
    const u_char* data = nullptr;
    const int rc = pcap_next_ex(as_pcap(pcap_), &header, &data);
    if (rc == PCAP_ERROR_BREAK) return false;  // clean end of file
    if (rc != 1) {
      // A record header that promises more than the file holds, or a corrupt one: libpcap cannot
      // resynchronise, so this pass ends here, and the source says so (a replay cut short must
      // not end looking like a whole one).
      last_error_ = pcap_geterr(as_pcap(pcap_));
      if (last_error_.find("truncated") != std::string::npos) {
        ++stats_.truncated;
      } else {
        ++stats_.malformed;
      }
      if (end_error_.empty()) end_error_ = cut_short_text();
      return false;
    }
    ++records_;
    // Classic pcap's seconds are unsigned 32-bit (good to 2106), but libpcap reads them signed:
    // a record from 2038 on comes out negative.
    if (classic_ && header->ts.tv_sec < 0) header->ts.tv_sec += 4'294'967'296LL;
    // A corrupt pcapng timestamp (64-bit ticks) can be 2^64 seconds: the product would overflow.
    if (header->ts.tv_sec < 0 || header->ts.tv_sec >= kMaxReceiveTimeNs / 1'000'000'000 ||
        header->ts.tv_usec < 0 || header->ts.tv_usec >= 1'000'000'000) {
      ++stats_.malformed;
      last_error_ = "record " + std::to_string(records_) + " has an impossible timestamp (" +
                    std::to_string(header->ts.tv_sec) + " s " + std::to_string(header->ts.tv_usec) +
                    " ns)";
      continue;
    }
    const int64_t stamp_ns = static_cast<int64_t>(header->ts.tv_sec) * 1'000'000'000 +
                             static_cast<int64_t>(header->ts.tv_usec);  // ns precision
    if (have_first_) {
      if (stamp_ns > last_ns_) last_interval_ns_ = stamp_ns - last_ns_;
    } else {
      have_first_ = true;
      first_ns_ = stamp_ns;
    }
    last_ns_ = stamp_ns;

    UdpView udp;
    FrameStatus status;
    if (!accept_udp_frame(static_cast<LinkType>(link_type_), {data, header->caplen},
                          {options_.data_port, options_.position_port, options_.sensor_ipv4}, udp,
                          stats_, status)) {
      if (status == FrameStatus::kFragment) ++fragments_;
      continue;
    }
    pending_packet_.payload = udp.payload;
    pending_packet_.receive_time_ns = stamp_ns + shift_ns_;
    pending_packet_.source_ipv4 = udp.source_ipv4;
    pending_packet_.destination_port = udp.destination_port;
    return true;
  }
}

std::string PcapSource::cut_short_text() const {
  // Bytes left after the record that stopped libpcap: none when the file ends inside its last
  // record (a recording cut short: one packet lost, counted as truncated, the replay whole).
  FILE* file = pcap_file(as_pcap(pcap_));
  struct stat st {};
  if (file == nullptr || ::fstat(::fileno(file), &st) != 0 || !S_ISREG(st.st_mode)) {
    return "capture '" + path_ + "' is unreadable after record " + std::to_string(records_) + " (" +
           last_error_ + "): the replay stopped there";
  }
  const long at = std::ftell(file);
  if (at < 0 || at >= st.st_size) return {};
  return "capture '" + path_ + "' is unreadable after record " + std::to_string(records_) + " (" +
         last_error_ + "): the replay stopped there, " + std::to_string(st.st_size - at) +
         " of its " + std::to_string(st.st_size) + " bytes not read";
}

bool PcapSource::restart() {
  // A pass that delivered nothing would loop forever without progress.
  if (!options_.loop || delivered_this_pass_ == 0) return false;
  // Receive times stay below 2 kMaxReceiveTimeNs (no overflow): the loop ends after ~136 years.
  const int64_t step = (last_ns_ - first_ns_) + std::max(last_interval_ns_, kMinLoopGapNs);
  if (shift_ns_ > kMaxReceiveTimeNs - step) return false;
  close();
  open();
  shift_ns_ += step;
  have_first_ = false;
  delivered_this_pass_ = 0;
  return true;
}

ReadStatus PcapSource::next(RawPacket& out, std::chrono::milliseconds timeout) {
  while (!pending_) {
    if (read_packet()) {
      pending_ = true;
      break;
    }
    ++passes_;
    if (!restart()) {
      close();
      return ReadStatus::kEnd;
    }
  }
  if (options_.pacing == ReplayPacing::kCaptureTime &&
      !schedule_.wait(pending_packet_.receive_time_ns, timeout)) {
    return ReadStatus::kTimeout;
  }
  pending_ = false;
  out = pending_packet_;
  ++delivered_this_pass_;
  ++stats_.packets;
  stats_.bytes += out.payload.size();
  return ReadStatus::kPacket;
}

}  // namespace lidartag::driver
