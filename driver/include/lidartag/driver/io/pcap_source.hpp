// Replays a pcap or pcapng capture (anything libpcap's pcap_open_offline reads) as a PacketSource.
// Link types: Ethernet (with VLAN tags), Linux cooked capture v1/v2, raw IP / raw IPv4. Only IPv4
// UDP to the data or position port is delivered; everything else is counted, never read past.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "lidartag/driver/io/errors.hpp"
#include "lidartag/driver/io/udp_frame.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::driver {

enum class ReplayPacing : uint8_t {
  kAsFastAsPossible,  // no waiting: tools and tests
  kCaptureTime,       // follow the capture timestamps, scaled by `rate`
};

struct PcapSourceOptions {
  uint16_t data_port = kDefaultDataPort;          // UDP destination port of data packets
  uint16_t position_port = kDefaultPositionPort;  // UDP destination port of position packets
  // Only packets from this sender (IPv4, host byte order) are delivered; others are
  // counted in `foreign_source`.
  // Empty: any sender. Needed when one capture holds several sensors on the same ports.
  std::optional<uint32_t> sensor_ipv4;
  ReplayPacing pacing = ReplayPacing::kAsFastAsPossible;
  // With kCaptureTime: speed factor, 1 = real time, 2 = twice as fast. Must be > 0.
  double rate = 1.0;
  // Start again at the end of the file. Receive times keep growing: each pass is shifted by the
  // capture's duration plus its last packet interval, so time stays monotonic.
  bool loop = false;
};

// When to hand out a packet under kCaptureTime pacing: pure arithmetic, separate for testing.
// The first packet anchors capture time to the steady clock; packet t is due at
// anchor + (t - t_first) / rate.
class ReplaySchedule {
 public:
  using Clock = std::chrono::steady_clock;
  explicit ReplaySchedule(double rate) : rate_(rate) {}
  // Due time of a packet captured at `capture_ns`; the first call anchors at `now`.
  Clock::time_point due(int64_t capture_ns, Clock::time_point now);
  // Sleeps until that packet is due and returns true, or, when it is due later than `timeout`
  // from now, sleeps `timeout` and returns false (the caller reports a timeout).
  bool wait(int64_t capture_ns, std::chrono::milliseconds timeout);
  void reset() { anchored_ = false; }

 private:
  double rate_;
  bool anchored_ = false;
  int64_t first_capture_ns_ = 0;
  Clock::time_point anchor_{};
};

class PcapSource final : public PacketSource {
 public:
  // Opens `path`; throws IoError naming the file with libpcap's message, or when the link type is
  // not supported, or when the options are invalid (rate <= 0).
  explicit PcapSource(const std::string& path, PcapSourceOptions options = {});
  ~PcapSource() override;
  PcapSource(const PcapSource&) = delete;
  PcapSource& operator=(const PcapSource&) = delete;

  // Next UDP payload to the data or position port. Returns kTimeout only under kCaptureTime pacing
  // when the next packet is not due within `timeout` (the packet stays pending); kEnd at the end
  // (also after a record that cuts the file short or a corrupt record header, counted).
  ReadStatus next(RawPacket& out, std::chrono::milliseconds timeout) override;
  SourceStats stats() const override { return stats_; }
  // The first record that cut a pass short (libpcap cannot read past a corrupt record header),
  // with what was left unread; empty when every pass read its file to the end (a file that ends
  // inside its last record, as a recording stopped mid-write does, counts as read: that record
  // is counted in SourceStats::truncated).
  std::string error() const override { return end_error_; }

  int link_type() const { return link_type_; }       // libpcap DLT_ value
  uint64_t records() const { return records_; }      // capture records read, all passes
  uint64_t fragments() const { return fragments_; }  // IPv4 fragments (also in `ignored`)
  uint64_t passes() const { return passes_; }        // completed passes over the file (loop)
  // Last reading problem (truncated file, corrupt record) as libpcap reported it, else empty.
  const std::string& last_error() const { return last_error_; }
  const std::string& path() const { return path_; }

 private:
  void open();
  void close();
  // Reads records until one is deliverable; false at the end of this pass.
  bool read_packet();
  bool restart();
  std::string cut_short_text() const;

  // The file's stdio buffer (it outlives the pcap_t that reads through it).
  static constexpr size_t kReadBufferBytes = 64 * 1024;
  std::unique_ptr<char[]> read_buffer_;
  std::string path_;
  PcapSourceOptions options_;
  void* pcap_ = nullptr;  // pcap_t*
  int link_type_ = 0;
  SourceStats stats_{};
  uint64_t records_ = 0, fragments_ = 0, passes_ = 0;
  uint64_t delivered_this_pass_ = 0;
  std::string last_error_;
  std::string end_error_;
  bool classic_ = false;  // classic pcap (32-bit seconds), not pcapng
  ReplaySchedule schedule_;
  // The packet read but not yet handed out (paced replay waiting for its time).
  bool pending_ = false;
  RawPacket pending_packet_{};
  // Loop bookkeeping, in capture time: first and last record stamps of the pass, the last
  // interval, and the shift added to receive times of the current pass.
  bool have_first_ = false;
  int64_t first_ns_ = 0, last_ns_ = 0, last_interval_ns_ = 0, shift_ns_ = 0;
};

}  // namespace lidartag::driver
