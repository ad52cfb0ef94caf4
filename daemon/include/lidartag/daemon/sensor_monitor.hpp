// What one sensor's pipeline reports. The data path (SensorPipeline) publishes counters here as it
// goes: the rotation counts (assembled, published, dropped, in the pipeline), the receiving loop's
// heartbeat, and after each read of the source a copy of the reader's counters, the senders seen
// and the model verdict. From them this unit makes the status, the health and the watchdog's
// verdict (progressing), on the status thread, never touching the data path's objects.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/health.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/driver/scan_reader.hpp"

namespace lidartag::daemon {

// The rotation counters, changed together so that every status sees
// assembled = published + behind + seam + unsent + in_flight.
struct RotationCounts {
  uint64_t assembled = 0, published = 0, behind = 0, seam = 0, unsent = 0, in_flight = 0;
  uint64_t detections = 0;
  int64_t last_assembled_ns = 0;  // steady clock
  int64_t progress_ns = 0;        // last publication, or when the pipeline last became non-empty
  uint64_t dropped() const { return behind + seam + unsent; }
};

// What the status reads of the data path's parts, at the time it is made.
struct PathGauges {
  uint64_t packets_received = 0;  // by the source (TapSource::packets)
  uint64_t publish_failures = 0;  // this sensor's LCM messages not published
  uint64_t bus_failures = 0;      // the bus's, status messages included
  size_t buffer_waiting = 0, buffer_depth = 0;
  bool finished = false;       // the source ended and everything was published
  uint64_t size_warnings = 0;  // detections whose measured size contradicts the configured one
  std::string size_note;       // the latest of them
};

class SensorMonitor {
 public:
  SensorMonitor(const SensorOptions& sensor, const DaemonOptions& options);
  ~SensorMonitor();
  SensorMonitor(const SensorMonitor&) = delete;
  SensorMonitor& operator=(const SensorMonitor&) = delete;

  // ---- Published by the data path ----
  // The data port the reader uses (the vendor's, for a replay left at the default ports); before
  // started().
  void set_data_port(uint16_t port) { data_port_ = port; }
  void started(int64_t now_ns);
  // Receiving thread: every packet of the source (its sender, when on the data port).
  void note_sender(const driver::RawPacket& packet);
  // Receiving thread, after every read of the source: the reader's counters, and the rotation
  // just assembled (else null).
  void after_read(const driver::ScanReader& reader, const Scan* rotation);
  void beat(int64_t now_ns) { receiver_beat_ns_.store(now_ns, std::memory_order_relaxed); }
  // The receiving loop waits for the pipeline to free a slot (not a stall of its own).
  void waiting(bool waiting) { receiver_waiting_.store(waiting, std::memory_order_relaxed); }
  // The source ended: why it ended before its end (empty: it did not), and whether stop() did it.
  void receiver_done(std::string source_error, bool stopped);
  // A rotation assembled: counted, and its number (0, 1, ...) returned; one counted at a
  // replay's loop seam (not published); one dropped because detection was behind.
  uint64_t assembled(int64_t now_ns);
  void seam(int64_t now_ns);
  void dropped_behind();
  // A rotation left the pipeline: published (with its detections) or not.
  void published(bool sent, size_t detections, int64_t now_ns);
  uint64_t dropped() const;
  // The pipeline stopped on an error (the first one is kept).
  void fail(const std::string& what);

  // ---- Read by the status thread ----
  std::string error() const;
  std::string source_error() const;
  bool stopped() const { return stopped_.load(); }
  // The watchdog's verdict (SensorPipeline::progressing).
  bool progressing(int64_t now_ns, bool finished) const;
  // Counters and health now; `gauges` of the data path's parts at this time.
  SensorStatus status(int64_t now_ns, const PathGauges& gauges);

 private:
  struct Snapshot;
  struct Senders;
  std::string stall(int64_t now_ns) const;

  const SensorOptions& sensor_;
  const DaemonOptions& options_;
  uint16_t data_port_;
  HealthMonitor health_;
  std::atomic<int64_t> started_ns_{0}, receiver_beat_ns_{0};
  std::atomic<bool> receiver_waiting_{false}, receiver_done_{false}, stopped_{false};
  std::unique_ptr<Senders> senders_;  // receiving thread
  mutable std::mutex counts_mutex_;
  RotationCounts counts_;
  mutable std::mutex snapshot_mutex_;
  std::unique_ptr<Snapshot> snapshot_;
};

}  // namespace lidartag::daemon
