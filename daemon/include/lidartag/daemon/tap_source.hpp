// Wraps a sensor's PacketSource for the daemon: ends it on request (so the capture reader flushes
// and returns), counts packets for the status, and hands every packet to the taps (the --record
// pcap writer; the pipeline's, which notes senders and publishes the raw LCM channel).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/driver/packet_source.hpp"

namespace lidartag::daemon {

// The --record file, shared by every sensor's receiver thread. Packets are buffered by the writer
// and reach the file at least once a second. Write errors never propagate: on the first one
// recording stops, it is logged once (what failed, what the file holds), and every later packet
// is counted as not recorded.
class PcapRecorder {
 public:
  static constexpr int64_t kFlushPeriodNs = 1'000'000'000;

  explicit PcapRecorder(const std::string& path);  // throws driver::IoError
  void write(const driver::RawPacket& packet) noexcept;
  // Writes what is buffered and closes the file; a failure then counts like a write error.
  void close() noexcept;
  // Packets in the file (after close() or a failure exactly those; before, buffered ones too).
  uint64_t records() const;
  // Packets handed to write() that are not in the file (lost at or after a failure).
  uint64_t missed() const;
  bool failed() const;
  // Empty while all went well; else what failed and what the file holds, e.g. "cannot write
  // 'x.pcap': No space left on device; the file holds the first 826 packets, 8211 received later
  // are not in it".
  std::string error() const;
  const std::string& path() const { return path_; }

 private:
  std::string error_text() const;  // mutex held
  void check_failure();            // mutex held: logs the first failure

  std::string path_;
  mutable std::mutex mutex_;
  driver::PcapWriter writer_;
  uint64_t received_ = 0;
  int64_t next_flush_ns_ = 0;
  bool reported_ = false;
};

class TapSource final : public driver::PacketSource {
 public:
  using RawTap = std::function<void(const driver::RawPacket&)>;

  // `recorder` may be null; `raw_tap` may be empty.
  TapSource(std::unique_ptr<driver::PacketSource> inner, PcapRecorder* recorder, RawTap raw_tap);

  // Waits at most 100 ms per call, so that stop() is noticed quickly; kEnd once stopped.
  driver::ReadStatus next(driver::RawPacket& out, std::chrono::milliseconds timeout) override;
  driver::SourceStats stats() const override;  // the inner source's (its thread only)
  std::string error() const override { return inner_->error(); }  // its thread only

  void stop() { stop_.store(true, std::memory_order_relaxed); }
  // Any thread.
  uint64_t packets() const { return packets_.load(std::memory_order_relaxed); }

 private:
  std::unique_ptr<driver::PacketSource> inner_;
  PcapRecorder* recorder_;
  RawTap raw_tap_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> packets_{0};
};

// Steady-clock nanoseconds (for latencies and progress).
int64_t steady_ns();

}  // namespace lidartag::daemon
