#include "lidartag/daemon/rotation_publisher.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "lidartag/daemon/ego_motion_input.hpp"
#include "lidartag/daemon/mcap_recorder.hpp"
#include "lidartag/daemon/messages.hpp"
#include "lidartag/daemon/sensor_pipeline.hpp"
#include "lidartag/daemon/tap_source.hpp"

namespace lidartag::daemon {

namespace {

enum FixedStage : size_t { kQueue, kDetect, kOrder, kPublish, kTotal, kFixedStages };

double ms(int64_t ns) {
  return static_cast<double>(ns) * 1e-6;
}

}  // namespace

void FailureLog::line(uint64_t count, std::chrono::steady_clock::time_point now) {
  const uint64_t fresh = count - logged_;
  spdlog::warn("sensor {}: {} LCM message{} not published{} (last on {}; {} in all)", sensor_,
               fresh, fresh == 1 ? "" : "s", logged_ == 0 ? "" : " since the last report",
               last_channel_, count);
  last_line_ = now;
  logged_ = count;
}

void FailureLog::failed(const std::string& channel) {
  const uint64_t count = count_.fetch_add(1, std::memory_order_relaxed) + 1;
  std::lock_guard lock(mutex_);
  last_channel_ = channel;
  const auto now = std::chrono::steady_clock::now();
  if (logged_ != 0 && now - last_line_ < interval_) return;
  line(count, now);
}

void FailureLog::report() {
  const uint64_t count = count_.load(std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  if (count > logged_ && now - last_line_ >= interval_) line(count, now);
}

RotationPublisher::RotationPublisher(const SensorOptions& sensor, const DaemonOptions& options,
                                     LcmBus& bus, LinePrinter* printer, FailureLog& failures)
    : sensor_(sensor),
      options_(options),
      bus_(bus),
      printer_(printer),
      failures_(failures),
      detections_channel_(channel_of(sensor, options.lcm.channels.detections)),
      tag_points_channel_(channel_of(sensor, options.lcm.channels.tag_points)),
      cloud_channel_(channel_of(sensor, options.lcm.channels.cloud)) {
  if (options.tracker.enabled) tracker_.emplace(options.tracker, options.detector);
  for (size_t i = 0; i < options.sensors.size(); ++i)
    if (options.sensors[i].name == sensor.name) sensor_index_ = i;
  stage_names_ = {"queue", "detect", "order", "publish", "total"};
  for (int s = 0; s < detector::kStageCount; ++s) {
    stage_names_.emplace_back(detector::stage_name(static_cast<detector::Stage>(s)));
  }
  for (size_t i = 0; i < stage_names_.size(); ++i) {
    windows_.push_back(std::make_unique<LatencyWindow>());
  }
}

bool RotationPublisher::publish(const RotationResult& r, uint64_t dropped) {
  const int64_t before = steady_ns();
  fill_detections(r, sensor_.name, sensor_.frame_id, wall_utime(), ms(before - r.assembled_ns),
                  static_cast<int64_t>(dropped), message_);
  if (tracker_) {
    // Every rotation reaches this point in order; dropped ones need nothing (tracks age by the
    // scan's time, and a stamp that steps back, a looping replay, ends every track).
    // With the robot's motion (config ego_motion): candidates placed in its odometry frame.
    if (EgoMotionInput* ego = bus_.ego_motion()) {
      ego->read(sensor_index_, [&](const detector::EgoMotion& e) {
        tracker_->update(r.detection, r.stamp_ns, tracked_, &e);
      });
      ego_placed_.fetch_add(static_cast<uint64_t>(std::max(tracked_.ego_placed, 0)),
                            std::memory_order_relaxed);
      ego_missing_.fetch_add(static_cast<uint64_t>(std::max(tracked_.ego_missing, 0)),
                             std::memory_order_relaxed);
    } else {
      tracker_->update(r.detection, r.stamp_ns, tracked_);
    }
    if (options_.detector.deskew.enabled) {
      std::lock_guard lock(motion_mutex_);
      motion_ = tracker_->motion();
    }
    fill_tracked_detections(tracked_, message_);
    for (const detector::TrackedDetection& t : tracked_.tags) check_size(t.detection);
  } else {
    for (const detector::Detection& d : r.detection.detections) check_size(d);
  }
  const bool sent = bus_.publish(detections_channel_, message_);
  if (!sent) failures_.failed(detections_channel_);
  // The visualisation messages follow their rotation's detections, in rotation order too.
  if (options_.detector.keep_tag_points && !r.detection.detections.empty()) {
    fill_tag_points(r, sensor_.name, sensor_.frame_id, tag_points_message_);
    if (!bus_.publish(tag_points_channel_, tag_points_message_)) {
      failures_.failed(tag_points_channel_);
    }
  }
  if (options_.lcm.cloud_decimation > 0) {
    fill_point_cloud(r, sensor_.name, sensor_.frame_id, cloud_message_);
    if (!bus_.publish(cloud_channel_, cloud_message_)) failures_.failed(cloud_channel_);
  }
  if (mcap_ != nullptr) mcap_->rotation(sensor_, r, tracker_ ? &tracked_ : nullptr);
  const int64_t after = steady_ns();
  windows_[kQueue]->record(ms(r.taken_ns - r.assembled_ns));
  windows_[kDetect]->record(ms(r.detected_ns - r.taken_ns));
  windows_[kOrder]->record(ms(before - r.detected_ns));
  windows_[kPublish]->record(ms(after - before));
  windows_[kTotal]->record(ms(after - r.assembled_ns));
  for (size_t s = 0; s < r.detection.timing_ms.size(); ++s) {
    windows_[kFixedStages + s]->record(r.detection.timing_ms[s]);
  }
  if (printer_ != nullptr) printer_->print(detections_line(sensor_.name, r));
  return sent;
}

detector::Motion RotationPublisher::motion() const {
  std::lock_guard lock(motion_mutex_);
  return motion_;
}

void RotationPublisher::check_size(const detector::Detection& d) {
  if (!d.size_warning) return;
  size_warnings_.fetch_add(1, std::memory_order_relaxed);
  std::lock_guard lock(size_mutex_);
  last_size_.family = {};
  d.family.copy(last_size_.family.data(), last_size_.family.size() - 1);
  last_size_.id = d.id;
  last_size_.size_m = d.size_m;
  last_size_.measured_m = d.measured_size_m;
}

std::string RotationPublisher::size_note() const {
  std::lock_guard lock(size_mutex_);
  if (last_size_.id < 0) return "";
  return fmt::format("{} id {} measures {:.3f} m, configured {:.3f} m", last_size_.family.data(),
                     last_size_.id, last_size_.measured_m, last_size_.size_m);
}

std::vector<Percentiles> RotationPublisher::take_latencies() {
  std::vector<Percentiles> out;
  out.reserve(windows_.size());
  for (auto& w : windows_) out.push_back(w->take());
  return out;
}

}  // namespace lidartag::daemon
