// The in-order stage of a sensor's pipeline: called serially, in rotation order, once per detected
// rotation. It publishes the rotation's detections (then its visualisation messages) on LCM,
// prints the --print-detections line, records the stage latencies and counts what could not be
// sent (logged at most once every few seconds, with the count). The sensor's tracker (evidence over
// rotations) sees every rotation here, in order, before its messages are filled.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/latency_window.hpp"
#include "lidartag/daemon/lcm_bus.hpp"
#include "lidartag/daemon/rotation.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/point_cloud_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "lidartag/tag_points_t.hpp"

namespace lidartag::daemon {

class LinePrinter;
class McapRecorder;

// Publish failures of one sensor, from any thread: counted, and logged at most once per
// `interval` with the number since the last line.
class FailureLog {
 public:
  FailureLog(std::string sensor, std::chrono::steady_clock::duration interval)
      : sensor_(std::move(sensor)), interval_(interval) {}
  void failed(const std::string& channel);
  // Logs the failures not logged yet, when the last line is `interval` old (the status calls it,
  // so that a burst that ended is reported too).
  void report();
  uint64_t count() const { return count_.load(std::memory_order_relaxed); }

 private:
  std::string sensor_;
  std::chrono::steady_clock::duration interval_;
  std::atomic<uint64_t> count_{0};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point last_line_{};
  uint64_t logged_ = 0;  // count at the last line
  std::string last_channel_;
  void line(uint64_t count, std::chrono::steady_clock::time_point now);
};

class RotationPublisher {
 public:
  // `printer` may be null. Throws detector::OptionsError for tracker options that break its rules
  // (at setup: the configuration was checked already).
  RotationPublisher(const SensorOptions& sensor, const DaemonOptions& options, LcmBus& bus,
                    LinePrinter* printer, FailureLog& failures);

  // Publishes `r`, the next rotation in order; `dropped`: rotations dropped so far (in the
  // message). True when its detections message was sent.
  bool publish(const RotationResult& r, uint64_t dropped);
  // Also writes every published rotation to `mcap` (null: none); before the pipeline starts.
  void record_to(McapRecorder* mcap) { mcap_ = mcap; }

  // Stage latencies, milliseconds: queue (assembled -> taken), detect, order (waiting for earlier
  // rotations), publish, total, then the detector's own stages.
  const std::vector<std::string>& stage_names() const { return stage_names_; }
  // Percentiles since the previous call, one per stage (any thread).
  std::vector<Percentiles> take_latencies();
  // The size check: detections published whose points measure another size than the configured
  // one (Detection::size_warning), and the latest of them in words (any thread).
  uint64_t size_warnings() const { return size_warnings_.load(std::memory_order_relaxed); }
  std::string size_note() const;
  // With the ego-motion input: the tracker's candidates placed in the odometry frame, and those
  // its poses did not cover (TrackerResult::ego_placed, ego_missing), summed (any thread).
  uint64_t ego_placed() const { return ego_placed_.load(std::memory_order_relaxed); }
  uint64_t ego_missing() const { return ego_missing_.load(std::memory_order_relaxed); }
  // The tracker's model of how the static world moves through the sensor's frame after the
  // latest rotation (detector::Tracker::motion(); unknown without a tracker): the deskew's when
  // no odometry covers a cluster (any thread).
  detector::Motion motion() const;
  // This sensor's index in DaemonOptions::sensors (its ego-motion poses).
  size_t sensor_index() const { return sensor_index_; }

 private:
  const SensorOptions& sensor_;
  const DaemonOptions& options_;
  LcmBus& bus_;
  LinePrinter* printer_;
  FailureLog& failures_;
  McapRecorder* mcap_ = nullptr;
  std::string detections_channel_, tag_points_channel_, cloud_channel_;
  lidartag::tag_detections_t message_;  // reused: no allocation once grown
  lidartag::tag_points_t tag_points_message_;
  lidartag::point_cloud_t cloud_message_;
  std::optional<detector::Tracker> tracker_;  // tracker.enabled
  size_t sensor_index_ = 0;
  std::atomic<uint64_t> ego_placed_{0}, ego_missing_{0};
  mutable std::mutex motion_mutex_;
  detector::Motion motion_;  // the tracker's after the latest rotation
  // The size check's latest warning (the family's name copied: no allocation while publishing).
  struct SizeSeen {
    std::array<char, 32> family{};
    int id = -1;
    double size_m = 0.0, measured_m = 0.0;
  };
  void check_size(const detector::Detection& d);
  std::atomic<uint64_t> size_warnings_{0};
  mutable std::mutex size_mutex_;
  SizeSeen last_size_;
  detector::TrackerResult tracked_;  // reused: no allocation once grown
  std::vector<std::string> stage_names_;
  std::vector<std::unique_ptr<LatencyWindow>> windows_;
};

}  // namespace lidartag::daemon
