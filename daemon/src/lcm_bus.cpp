#include "lidartag/daemon/lcm_bus.hpp"

namespace lidartag::daemon {

LcmBus::LcmBus(const std::string& url) : url_(url), lcm_(url) {
  if (!lcm_.good()) {
    throw LcmError("cannot open LCM with URL '" + (url.empty() ? std::string("(default)") : url) +
                   "' (bad provider, or no multicast route: see docs/daemon.md)");
  }
}

bool LcmBus::send(const std::string& channel, int size) {
  if (lcm_.publish(channel, buffer_.data(), static_cast<unsigned>(size)) != 0) {
    ++failures_;
    return false;
  }
  ++published_;
  return true;
}

uint64_t LcmBus::failures() const {
  std::lock_guard lock(mutex_);
  return failures_;
}

uint64_t LcmBus::published() const {
  std::lock_guard lock(mutex_);
  return published_;
}

}  // namespace lidartag::daemon
