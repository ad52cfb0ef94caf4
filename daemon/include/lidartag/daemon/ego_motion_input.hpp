// The robot's own motion, received on LCM (config ego_motion; lcmtypes/ego_motion_t.lcm): each
// message, moved from the robot's body to the LiDAR by the configured mount, goes into a
// detector::EgoMotion that the sensors' trackers read (under a lock) in rotation order. Bad
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

#include "lidartag/daemon/config.hpp"
#include "lidartag/detector/ego_motion.hpp"
#include "lidartag/ego_motion_t.hpp"

namespace lidartag::daemon {

// The LiDAR's pose on the body (sensor frame -> body frame), from the configuration.
struct SensorMount {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};
SensorMount sensor_mount(const EgoMotionConfig& config);

// What became of one message.
enum class EgoMessage : unsigned char { kAccepted, kOutOfOrder, kInvalid, kUnknownKind };

// One message into `ego`: a pose of the body becomes the sensor's (body pose * mount), a twist of
// the body the sensor's (v + w x p, turned into the sensor's frame). Pure; never throws.
EgoMessage apply_ego_message(const lidartag::ego_motion_t& message, const SensorMount& mount,
                             detector::EgoMotion& ego) noexcept;

struct EgoMotionCounts {
  uint64_t received = 0, accepted = 0, out_of_order = 0, invalid = 0, unknown_kind = 0,
           undecodable = 0;
};

class EgoMotionInput {
 public:
  // Opens LCM on config.url (empty: `default_url`) and subscribes to config.channel; starts
  // nothing. Throws LcmError (no LCM, a file:// URL, no multicast route) or
  // detector::OptionsError (bad buffer options).
  EgoMotionInput(const EgoMotionConfig& config, const std::string& default_url);
  ~EgoMotionInput();

  // Receives on a thread of its own until stop() (or destruction).
  void start();
  void stop();

  // Handles what has arrived, up to timeout_ms (the thread's loop; tests call it directly).
  void poll(int timeout_ms);

  // Runs f(const detector::EgoMotion&) with the samples locked (the trackers' update).
  template <class F>
  void read(F&& f) const {
    std::lock_guard lock(mutex_);
    f(static_cast<const detector::EgoMotion&>(ego_));
  }

  // Counters (any thread).
  EgoMotionCounts counts() const;
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

  EgoMotionConfig config_;
  SensorMount mount_;
  std::unique_ptr<lcm::LCM> lcm_;
  mutable std::mutex mutex_;
  detector::EgoMotion ego_;
  EgoMotionCounts counts_;
  int64_t last_host_ns_ = 0;  // steady clock of the last accepted message; 0: none yet
  uint64_t logged_problems_ = 0;
  int64_t next_log_ns_ = 0;
  bool stale_logged_ = false;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace lidartag::daemon
