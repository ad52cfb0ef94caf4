// Replays the raw packets of an LCM log (raw_packet_t on one channel, as recorded by lcm-logger
// from lidartagd's raw channel) as a PacketSource. Messages that do not decode are counted as
// malformed and skipped, never fatal (LCM's generated decode() throws on some bad input); a log
// that ends inside an event (cut short, corrupt event header) counts as truncated.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/raw_packet_t.hpp"

namespace lcm {
class LogFile;
}

namespace lidartag::daemon {

struct LcmLogSourceOptions {
  std::string channel = "LIDARTAG_RAW";  // events on other channels are ignored
  double rate = 0.0;                     // 0: as fast as possible; 1: the recorded pace
  bool loop = false;                     // start again at the end (times keep growing)
};

class LcmLogSource final : public driver::PacketSource {
 public:
  // Opens the log; throws driver::IoError naming the file.
  LcmLogSource(const std::string& path, LcmLogSourceOptions options);
  ~LcmLogSource() override;

  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds timeout) override;
  driver::SourceStats stats() const override { return stats_; }
  uint64_t events() const { return events_; }  // log events read, all channels and passes

 private:
  bool read_one();  // the next deliverable packet into message_; false at the end of the file
  // Whether the next event's claimed lengths fit in the file (else LCM would allocate them).
  bool next_event_fits();

  std::string path_;
  LcmLogSourceOptions options_;
  std::unique_ptr<lcm::LogFile> log_;
  lidartag::raw_packet_t message_;
  driver::ReplaySchedule schedule_;
  driver::SourceStats stats_{};
  uint64_t events_ = 0;
  bool pending_ = false;
  int64_t time_ns_ = 0;  // receive time of message_, shifted for loops
  int64_t first_ns_ = 0, last_ns_ = 0, last_interval_ns_ = 0, shift_ns_ = 0;
  bool have_first_ = false;
  long file_size_ = 0, end_of_events_ = 0;  // bytes; past the last whole event read
};

}  // namespace lidartag::daemon
