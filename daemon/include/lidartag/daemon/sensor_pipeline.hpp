// One sensor's pipeline: a receiving thread (source -> capture reader: decoding and scan assembly)
// hands rotations to the lock-free scan buffer; detection tasks in the shared oneTBB arena take
// them (one Detector per worker, rotations in parallel), the reorder stage puts the results back
// in rotation order, and a publisher thread sends them on LCM.
//
//   receiver --ScanBuffer (drop oldest)--> TBB workers --OrderedResults--> publisher -> LCM
#pragma once

#include <tbb/task_arena.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/latency_window.hpp"
#include "lidartag/daemon/lcm_bus.hpp"
#include "lidartag/daemon/ordered_results.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/daemon/tap_source.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/io/capture_reader.hpp"
#include "lidartag/driver/scan_buffer.hpp"
#include "lidartag/point_cloud_t.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "lidartag/tag_points_t.hpp"

namespace lidartag::daemon {

// Where --print-detections lines go (one line per rotation; shared by the sensors).
class LinePrinter {
 public:
  explicit LinePrinter(std::FILE* out) : out_(out) {}
  // One line, flushed. daemon-setup: when writing fails, printing stops and it is logged once;
  // when the reader closed the pipe (EPIPE) the daemon is asked to stop (a process-directed
  // SIGPIPE, which Daemon::run() takes).
  void print(const std::string& line);
  bool closed() const { return closed_.load(); }  // the output's reader went away

 private:
  std::mutex mutex_;
  std::FILE* out_;
  bool failed_ = false;
  std::atomic<bool> closed_{false};
};

// One line: "SENSOR #SEQ N tag(s): FAMILY:ID (x, y, z) m score S; ..." or "... 0 tags".
std::string detections_line(const std::string& sensor, const RotationResult& r);

class SensorPipeline {
 public:
  // Opens the source (velodyne::IoError), the calibration when the model is given
  // (velodyne::CalibrationError) and builds `workers` detectors (detector::OptionsError).
  SensorPipeline(const SensorOptions& sensor, const DaemonOptions& options, LcmBus& bus,
                 tbb::task_arena& arena, int workers, PcapRecorder* recorder, LinePrinter* printer);
  ~SensorPipeline();
  SensorPipeline(const SensorPipeline&) = delete;
  SensorPipeline& operator=(const SensorPipeline&) = delete;

  void start();
  // Ends the source: the rotation in progress is flushed, every rotation taken is published.
  void stop();
  // The source ended (replay done, or stopped) and everything was published.
  bool finished() const { return publisher_done_.load(std::memory_order_acquire); }
  void join();

  // Every stage ran within `stall_ns` and no rotation has been in detection longer.
  bool healthy(int64_t now_ns, int64_t stall_ns) const;
  // Counters now, latency percentiles since the previous call.
  SensorStatus status(int64_t now_ns, int64_t stall_ns);
  const SensorOptions& sensor() const { return sensor_; }
  // Set when the receiver stopped on an error (e.g. the calibration does not fit the model
  // decided from the packets); empty otherwise.
  std::string error() const;

 private:
  struct Snapshot;
  void receive();
  void publish_loop();
  void spawn();
  void work();
  void process(OrderedResults::Slot* slot);
  void publish(OrderedResults::Slot* slot);
  void take_snapshot(const Scan* last);
  int64_t assembled_at(const Scan* scan) const;
  uint64_t dropped_rotations() const;

  SensorOptions sensor_;
  const DaemonOptions& options_;
  LcmBus& bus_;
  tbb::task_arena& arena_;
  int workers_;
  LinePrinter* printer_;
  bool lossless_;
  std::string detections_channel_, raw_channel_, tag_points_channel_, cloud_channel_;

  TapSource* tap_ = nullptr;  // owned by reader_
  std::unique_ptr<velodyne::CaptureReader> reader_;
  std::vector<std::unique_ptr<detector::Detector>> detectors_;
  OrderedResults ordered_;
  std::unique_ptr<velodyne::ScanBuffer> buffer_;
  std::atomic<velodyne::ScanBuffer*> buffer_ptr_{nullptr};
  // Assembly time of each scan of the buffer (its scans are fixed: found once, at creation).
  std::vector<const Scan*> stamp_keys_;
  std::unique_ptr<std::atomic<int64_t>[]> stamp_times_;

  std::thread receiver_, publisher_;
  std::atomic<int> active_{0};  // detection tasks in the arena
  std::atomic<bool> source_done_{false}, publisher_done_{false}, stopping_{false};
  std::atomic<int64_t> publisher_beat_ns_{0};
  std::atomic<uint64_t> assembled_{0}, processed_{0}, published_{0}, detections_{0};
  std::atomic<uint64_t> dropped_no_scan_{0};

  lidartag::tag_detections_t message_;  // publisher thread
  lidartag::tag_points_t tag_points_message_;
  lidartag::point_cloud_t cloud_message_;
  lidartag::raw_packet_t raw_message_;  // receiver thread

  // Stage latencies: queue, detect, order, publish, total, then the detector's stages.
  std::vector<std::string> stage_names_;
  std::vector<std::unique_ptr<LatencyWindow>> windows_;

  mutable std::mutex snapshot_mutex_;
  std::unique_ptr<Snapshot> snapshot_;
};

}  // namespace lidartag::daemon
