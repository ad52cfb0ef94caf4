// The robot's own motion, received on LCM (config ego_motion; lcmtypes/ego_motion_t.lcm): each
// message, moved from the robot's body to each LiDAR by that LiDAR's mount, goes into one
// detector::EgoMotion per sensor that the sensor's tracker (and deskew) read under a lock. Bad
// messages (out of order, not finite, no rotation, an unknown kind, undecodable) are counted and
// logged at most once every few seconds, never fatal; a channel that goes quiet is stale (logged,
// and in health_note()), and the trackers then follow tags with their own motion model.
#pragma once

#include <atomic>
#include <cstdint>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/detector/ego_motion.hpp"
#include "lidartag/ego_motion_t.hpp"

namespace lidartag::daemon {

// The LiDAR's pose on the body (sensor frame -> body frame), from the configuration.
struct SensorMount {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};
SensorMount sensor_mount(const BodyMount& config);
// Every sensor's mount, in options.sensors' order (mount_of: its own, else the global one).
std::vector<SensorMount> sensor_mounts(const DaemonOptions& options);

// What became of one message.
enum class EgoMessage : unsigned char { kAccepted, kOutOfOrder, kInvalid, kUnknownKind };

// One message into `ego`: a pose of the body becomes the sensor's (body pose * mount), a twist of
// the body the sensor's (v + w x p, turned into the sensor's frame). Pure; never throws.
EgoMessage apply_ego_message(const lidartag::ego_motion_t& message, const SensorMount& mount,
                             detector::EgoMotion& ego) noexcept;

class EgoMotionInput {
 public:
  // Opens LCM on config.url (empty: `default_url`) and subscribes to config.channel; starts
  // nothing. `mounts`: one per sensor (sensor_mounts()); empty: one sensor, config's mount.
  // Throws LcmError (no LCM, a file:// URL, no multicast route) or detector::OptionsError (bad
  // buffer options).
  EgoMotionInput(const EgoMotionConfig& config, const std::string& default_url,
                 std::vector<SensorMount> mounts = {});
  ~EgoMotionInput();

  // Receives on a thread of its own until stop() (or destruction).
  void start();
  void stop();

  // Handles what has arrived, up to timeout_ms (the thread's loop; tests call it directly).
  void poll(int timeout_ms);

  // Runs f(const detector::EgoMotion&) with sensor `sensor`'s poses locked (its tracker's update,
  // a copy for its deskew); a sensor out of range reads the first.
  template <class F>
  void read(size_t sensor, F&& f) const {
    std::lock_guard lock(mutex_);
    f(static_cast<const detector::EgoMotion&>(ego_[sensor < ego_.size() ? sensor : 0]));
  }
  template <class F>
  void read(F&& f) const {
    read(0, std::forward<F>(f));
  }
  size_t sensors() const { return ego_.size(); }

  // Counters (any thread).
  EgoMotionCounts counts() const;
  // Counters, staleness and age now (any thread).
  EgoMotionState state() const;
  // "" while messages arrive in time; else why the trackers may be without it, in words
  // (nothing received yet, stale for N s, out-of-order messages), for a status line.
  std::string health_note() const;
  const std::string& channel() const { return config_.channel; }
  lcm::LCM& lcm() { return *lcm_; }  // for tests: publish into a memq:// instance

 private:
  // Through LCM's C API: lcm-cpp's member-function subscription trips UBSan's vptr check on its
  // own subscription object when dispatched from a memq:// instance.
  static void on_raw(const lcm_recv_buf_t* buffer, const char* channel, void* self);
  void on_message(const void* data, uint32_t size);
  void log_problems();
  // Whether the channel is stale at `now_ns`; counts the episodes. Under mutex_.
  bool stale_at(int64_t now_ns) const;

  EgoMotionConfig config_;
  std::vector<SensorMount> mounts_;
  std::unique_ptr<lcm::LCM> lcm_;
  mutable std::mutex mutex_;
  std::vector<detector::EgoMotion> ego_;  // one per sensor (mounts_)
  mutable EgoMotionCounts counts_;        // stale_episodes counted by const readers too
  mutable bool stale_now_ = false;
  int64_t last_stamp_ns_ = 0;  // the last accepted message's stamp
  int64_t last_host_ns_ = 0;   // steady clock of the last accepted message; 0: none yet
  uint64_t logged_problems_ = 0;
  int64_t next_log_ns_ = 0;
  bool stale_logged_ = false;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace lidartag::daemon
