// The daemon's LCM connection: publishes generated types from any thread, encoding into a reused
// buffer (no allocation once it has grown to the largest message), and counts every message that
// was not delivered, whatever LCM 1.3.1 says:
// - udpm/mpudpm: LCM returns the error of a message sent in one datagram, but 0 for a message
//   sent in fragments (over 65,499 bytes, e.g. a point cloud) even when sendmsg() failed; the
//   failing sendmsg's errno is still set after the call, so that is checked too;
// - file://: written by LcmLogWriter instead of LCM's file provider, which ignores write errors.
// Failures are logged here, at most one line every kReportPeriodS seconds, with their count.
#pragma once

#include <cstdint>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "lidartag/daemon/lcm_log_writer.hpp"
#include "lidartag/daemon/lcm_url.hpp"

namespace lidartag::daemon {

class EgoMotionInput;

class LcmBus {
 public:
  static constexpr double kReportPeriodS = 5.0;

  // `url` empty: $LCM_DEFAULT_URL or LCM's default. Checks the URL (parse_lcm_url,
  // check_multicast_route) before LCM sees it; throws LcmError.
  explicit LcmBus(const std::string& url);
  ~LcmBus();

  // Encodes and publishes `message`; false (counted, logged rate-limited) when it was not
  // delivered.
  template <class Message>
  bool publish(const std::string& channel, const Message& message);

  // The LCM instance, for subscribing (tests). With a file:// URL the messages go to the log, not
  // to it: it is then an in-process memq:// instance that receives nothing.
  lcm::LCM& lcm() { return *lcm_; }
  const std::string& url() const { return url_.text; }  // as used (the default filled in)
  const std::string& provider() const { return url_.provider; }
  // The robot's motion received beside the bus (config ego_motion), for the trackers; null when
  // none. Set once at setup, before the pipelines start.
  void attach_ego_motion(EgoMotionInput* input) { ego_motion_ = input; }
  EgoMotionInput* ego_motion() const { return ego_motion_; }

  // Any thread.
  uint64_t failures() const;       // messages not delivered
  uint64_t published() const;      // messages delivered
  std::string last_error() const;  // "CHANNEL: why" of the last failure; empty until one

 private:
  bool send(const std::string& channel, size_t size);        // mutex held
  void failed(const std::string& channel, std::string why);  // mutex held

  LcmUrl url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::unique_ptr<LcmLogWriter> log_;  // file:// only
  bool multicast_ = false;             // udpm, mpudpm
  EgoMotionInput* ego_motion_ = nullptr;
  mutable std::mutex mutex_;
  std::vector<uint8_t> buffer_;
  uint64_t failures_ = 0, published_ = 0;
  std::string last_error_;
  // Rate-limited reporting: failures since the last line, when the next line may come.
  uint64_t unreported_ = 0;
  int64_t next_report_ns_ = 0;
  bool failing_ = false;  // the last line said messages are being lost
};

template <class Message>
bool LcmBus::publish(const std::string& channel, const Message& message) {
  std::lock_guard lock(mutex_);
  const int size = message.getEncodedSize();
  if (size < 0) {
    failed(channel, "cannot encode the message");
    return false;
  }
  if (buffer_.size() < static_cast<size_t>(size)) buffer_.resize(static_cast<size_t>(size));
  if (message.encode(buffer_.data(), 0, size) != size) {
    failed(channel, "cannot encode the message");
    return false;
  }
  return send(channel, static_cast<size_t>(size));
}

}  // namespace lidartag::daemon
