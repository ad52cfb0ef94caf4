// One sensor's pipeline: the receiving thread assembles each rotation straight into a slot of the
// scan buffer (CaptureReader::read: decoding and scan assembly, no copy) and tells a oneTBB flow
// graph in the shared arena, which takes the waiting slots in rotation order, detects them in
// parallel (one Detector per arena thread) and publishes them in rotation order
// (RotationPublisher), then frees the slot and takes the next.
//
//   receiver --ScanBuffer slot (drop oldest | wait)--> take (serial) -> detect (parallel)
//            -> sequencer -> publish (serial, in order) -> release, take again
//
// This file is the data path; what it counts goes to its SensorMonitor (sensor_monitor.hpp),
// which makes the status, the health and the watchdog's verdict.
#pragma once

#include <tbb/task_arena.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/health.hpp"
#include "lidartag/daemon/lcm_bus.hpp"
#include "lidartag/daemon/rotation.hpp"
#include "lidartag/daemon/rotation_publisher.hpp"
#include "lidartag/daemon/scan_buffer.hpp"
#include "lidartag/daemon/sensor_monitor.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/daemon/tap_source.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/scan_reader.hpp"
#include "lidartag/raw_packet_t.hpp"

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
  // Test seam: called in the detection stage before each rotation is detected (to slow detection
  // down or stall it in tests). Not reachable from the configuration.
  using DetectHook = std::function<void(const Scan&)>;

  // Opens the source (driver::IoError, driver::bag::BagError) through the vendor seam
  // (driver::open_capture, open_live), the calibration when the model is given
  // (velodyne::CalibrationError) or the Ouster metadata (driver::ouster::MetadataError) and builds
  // a detector for each rotation the pipeline may hold (workers + pipeline.publish_queue;
  // detector::OptionsError). `arena` has `workers` threads; none of them ever waits for the source,
  // and at most `workers` rotations are detected at once.
  SensorPipeline(const SensorOptions& sensor, const DaemonOptions& options, LcmBus& bus,
                 tbb::task_arena& arena, int workers, PcapRecorder* recorder, LinePrinter* printer,
                 DetectHook hook = {});
  ~SensorPipeline();
  SensorPipeline(const SensorPipeline&) = delete;
  SensorPipeline& operator=(const SensorPipeline&) = delete;

  // lidartagd --mcap: the published rotations also go to `mcap` (before start()).
  void record_mcap(McapRecorder* mcap) { publisher_.record_to(mcap); }
  void start();
  // Ends the source: the rotation in progress is flushed, every rotation taken is published.
  void stop();
  // The source ended (replay done, or stopped) and everything was published.
  bool finished() const { return finished_.load(std::memory_order_acquire); }
  void join();

  // What the systemd watchdog follows: the receiving loop runs, the rotations in the pipeline get
  // published, and rotations are assembled (or the sensor is waiting for its first packets within
  // health.startup_grace_s, or silent with watchdog.while_silent), each within
  // watchdog.stall_timeout_s. Any thread.
  bool progressing(int64_t now_ns) const { return monitor_.progressing(now_ns, finished()); }
  // Counters and health now, latency percentiles since the previous call (one thread).
  SensorStatus status(int64_t now_ns);
  const SensorOptions& sensor() const { return sensor_; }
  // Set when the pipeline stopped on an error (e.g. the calibration does not fit the model
  // decided from the packets); empty otherwise.
  std::string error() const { return monitor_.error(); }
  // Why the source ended before its end (a replay cut short by a corrupt record); else empty.
  std::string source_error() const { return monitor_.source_error(); }

 private:
  struct Graph;
  void receive();
  void wake_pipeline();
  template <class Out>
  void take(Out& out);
  void detect(Rotation& rotation);
  void publish(Rotation& rotation);
  bool at_loop_seam(const Scan& scan);

  SensorOptions sensor_;
  const DaemonOptions& options_;
  LcmBus& bus_;
  tbb::task_arena& arena_;
  int workers_;
  bool lossless_, loop_;
  DetectHook hook_;
  std::string raw_channel_;
  FailureLog failures_;
  SensorMonitor monitor_;

  TapSource* tap_ = nullptr;                    // owned by reader_
  std::unique_ptr<driver::ScanReader> reader_;  // any vendor's, by the source's content
  // One per rotation the pipeline may hold (indexed by Rotation::order modulo tokens_).
  std::vector<std::unique_ptr<detector::Detector>> detectors_;
  // With detector.deskew and an ego-motion input: each detector's copy of the sensor's poses,
  // taken under the input's lock before its rotation (the same index; no allocation once sized).
  std::vector<std::unique_ptr<detector::EgoMotion>> ego_copies_;
  ScanBuffer<Rotation> buffer_;
  RotationPublisher publisher_;
  size_t tokens_;  // rotations in the pipeline at most: workers + publish_queue
  std::unique_ptr<Graph> graph_;
  uint64_t taken_ = 0;                 // take() only (serial): also the next publication order
  std::atomic<uint64_t> released_{0};  // publish() (serial); in the pipeline: taken - released

  std::thread receiver_;
  std::atomic<bool> stopping_{false}, finished_{false};

  // Detected rotations' deskewed clusters: by the odometry, by the tracker's model, without.
  std::atomic<uint64_t> deskewed_ego_{0}, deskewed_model_{0}, deskew_without_motion_{0};

  lidartag::raw_packet_t raw_message_;  // receiver thread
  bool after_seam_ = false;             // receiver thread
};

}  // namespace lidartag::daemon
