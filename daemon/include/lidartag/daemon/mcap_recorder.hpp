// `lidartagd --mcap FILE`: what the daemon publishes, also written to an MCAP file for Foxglove
// (lidartag/foxglove/scene_recorder.hpp): per sensor and rotation its published cloud (when
// lcm.cloud_decimation > 0: the same decimated points), its detections (the tracker's, when it
// runs, as on LCM) as scene entities, frames and a JSON message, and each status as JSON. Log
// times are the rotations' stamps (the capture's clock); a status takes its sensor's latest
// rotation stamp (the wall clock before the first rotation).
// Called from every sensor's in-order stage and from the status loop: serialised by a mutex.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/rotation.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/foxglove/scene_recorder.hpp"

namespace lidartag::daemon {

class McapRecorder {
 public:
  // Creates `path`; throws driver::bag::McapWriteError.
  explicit McapRecorder(const std::string& path);

  // One published rotation of `sensor`; `tracked` null when the tracker is off. Never throws: a
  // failure is counted and logged once.
  void rotation(const SensorOptions& sensor, const RotationResult& r,
                const detector::TrackerResult* tracked);
  void status(const SensorStatus& s);

  // Completes the file and logs what it holds (or why it failed). Idempotent.
  void close();
  // Messages that could not be written (or a file that could not be completed).
  bool failed() const { return failures_.load() > 0; }
  const std::string& path() const { return path_; }

 private:
  void note_failure();

  std::string path_;
  std::mutex mutex_;
  foxglove::SceneRecorder recorder_;
  foxglove::CloudPoints points_;
  std::vector<detector::Detection> detections_;
  std::map<std::string, int64_t> last_stamp_;  // sensor -> latest rotation stamp
  std::atomic<uint64_t> failures_{0};
  bool closed_ = false;
};

}  // namespace lidartag::daemon
