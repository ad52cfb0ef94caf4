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

// The --record file, shared by every sensor's receiver thread. Write errors never propagate: the
// first one is remembered, recording stops, the daemon goes on.
class PcapRecorder {
 public:
  explicit PcapRecorder(const std::string& path);  // throws velodyne::IoError
  void write(const velodyne::RawPacket& packet) noexcept;
  void close() noexcept;
  uint64_t records() const;
  std::string error() const;  // empty while all went well

 private:
  mutable std::mutex mutex_;
  velodyne::PcapWriter writer_;
  std::string error_;
};

class TapSource final : public velodyne::PacketSource {
 public:
  using RawTap = std::function<void(const velodyne::RawPacket&)>;

  // `recorder` may be null; `raw_tap` may be empty.
  TapSource(std::unique_ptr<velodyne::PacketSource> inner, PcapRecorder* recorder, RawTap raw_tap);

  // Waits at most 100 ms per call, so that stop() is noticed quickly; kEnd once stopped.
  velodyne::ReadStatus next(velodyne::RawPacket& out, std::chrono::milliseconds timeout) override;
  velodyne::SourceStats stats() const override;  // the inner source's (its thread only)

  void stop() { stop_.store(true, std::memory_order_relaxed); }
  // Any thread.
  uint64_t packets() const { return packets_.load(std::memory_order_relaxed); }

 private:
  std::unique_ptr<velodyne::PacketSource> inner_;
  PcapRecorder* recorder_;
  RawTap raw_tap_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> packets_{0};
};

// Steady-clock nanoseconds (for latencies and progress).
int64_t steady_ns();

}  // namespace lidartag::daemon
