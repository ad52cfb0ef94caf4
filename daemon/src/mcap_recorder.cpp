#include "lidartag/daemon/mcap_recorder.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "lidartag/daemon/health.hpp"

namespace lidartag::daemon {

McapRecorder::McapRecorder(const std::string& path) : path_(path), recorder_(path) {}

void McapRecorder::note_failure() {
  if (failures_.fetch_add(1) == 0) {
    spdlog::error("--mcap {}: a message could not be written: {}", path_,
                  recorder_.writer().error().empty() ? "refused" : recorder_.writer().error());
  }
}

void McapRecorder::rotation(const SensorOptions& sensor, const RotationResult& r,
                            const detector::TrackerResult* tracked) {
  std::lock_guard lock(mutex_);
  if (closed_) return;
  try {
    const DecimatedCloud& c = r.cloud;
    points_.clear();
    for (size_t i = 0; i < c.size(); ++i) {
      points_.push(c.x[i], c.y[i], c.z[i], static_cast<float>(c.intensity[i]), c.ring[i]);
    }
    detections_.clear();
    if (tracked != nullptr) {
      for (const auto& t : tracked->tags) detections_.push_back(t.detection);
    } else {
      detections_.assign(r.detection.detections.begin(), r.detection.detections.end());
    }
    foxglove::RotationRecord rec;
    rec.sensor = sensor.name;
    rec.frame_id = sensor.frame_id;
    rec.sequence = r.sequence;
    rec.stamp_ns = r.stamp_ns;
    rec.cloud = c.decimation > 0 ? &points_ : nullptr;
    rec.detections = detections_;
    if (!recorder_.write_rotation(rec)) note_failure();
    last_stamp_[sensor.name] = r.stamp_ns;
  } catch (const std::exception&) {
    note_failure();  // out of memory while the buffers grew
  }
}

void McapRecorder::status(const SensorStatus& s) {
  std::lock_guard lock(mutex_);
  if (closed_) return;
  try {
    nlohmann::json j;
    j["sensor"] = s.sensor;
    j["frame_id"] = s.frame_id;
    j["state"] = std::string(health_state_name(s.health.state));
    j["reason"] = s.health.reason;
    j["healthy"] = s.health.healthy();
    j["model"] = s.model;
    j["return_mode"] = s.return_mode;
    j["rpm"] = s.rpm;
    j["packets_received"] = s.packets_received;
    j["packets_decoded"] = s.packets_decoded;
    j["packets_missing"] = s.packets_missing;
    j["packets_malformed"] = s.packets_malformed;
    j["rotations_assembled"] = s.rotations_assembled;
    j["rotations_published"] = s.rotations_published;
    j["rotations_dropped"] = s.rotations_dropped;
    j["detections"] = s.detections;
    j["publish_failures"] = s.publish_failures;
    if (!s.error.empty()) j["error"] = s.error;
    nlohmann::json stages = nlohmann::json::object();
    for (size_t i = 0; i < s.stage_names.size() && i < s.stages.size(); ++i) {
      stages[s.stage_names[i]] = {{"p50_ms", s.stages[i].p50}, {"p99_ms", s.stages[i].p99}};
    }
    j["latency"] = stages;
    const auto it = last_stamp_.find(s.sensor);
    const int64_t stamp = it != last_stamp_.end()
                              ? it->second
                              : std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                    .count();
    if (!recorder_.write_status(s.sensor, stamp, j.dump())) note_failure();
  } catch (const std::exception&) {
    note_failure();
  }
}

void McapRecorder::close() {
  std::lock_guard lock(mutex_);
  if (closed_) return;
  closed_ = true;
  try {
    recorder_.close();
    const auto& st = recorder_.writer().stats();
    const auto& n = recorder_.counts();
    spdlog::info("--mcap {}: {} messages ({} rotations, {} clouds, {} statuses), {} bytes", path_,
                 st.messages, n.scenes, n.clouds, n.statuses, st.bytes);
  } catch (const std::exception& e) {
    failures_.fetch_add(1);
    spdlog::error("--mcap {}: the file could not be completed: {}", path_, e.what());
  }
}

}  // namespace lidartag::daemon
