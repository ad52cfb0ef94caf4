// The daemon's LCM connection: publishes generated types from any thread, encoding into a reused
// buffer (no allocation once it has grown to the largest message).
#pragma once

#include <cstdint>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace lidartag::daemon {

// LCM could not be initialised with the URL (bad provider, no multicast route, ...).
class LcmError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class LcmBus {
 public:
  // `url` empty: LCM's default provider. Throws LcmError.
  explicit LcmBus(const std::string& url);

  // Encodes and publishes `message`; false (counted) when encoding or sending failed.
  template <class Message>
  bool publish(const std::string& channel, const Message& message);

  lcm::LCM& lcm() { return lcm_; }
  const std::string& url() const { return url_; }
  uint64_t failures() const;
  uint64_t published() const;

 private:
  bool send(const std::string& channel, int size);

  std::string url_;
  lcm::LCM lcm_;
  mutable std::mutex mutex_;
  std::vector<uint8_t> buffer_;
  uint64_t failures_ = 0, published_ = 0;
};

template <class Message>
bool LcmBus::publish(const std::string& channel, const Message& message) {
  std::lock_guard lock(mutex_);
  const int size = message.getEncodedSize();
  if (size < 0) {
    ++failures_;
    return false;
  }
  if (buffer_.size() < static_cast<size_t>(size)) buffer_.resize(static_cast<size_t>(size));
  if (message.encode(buffer_.data(), 0, size) != size) {
    ++failures_;
    return false;
  }
  return send(channel, size);
}

}  // namespace lidartag::daemon
