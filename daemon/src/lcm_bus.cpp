#include "lidartag/daemon/lcm_bus.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "lidartag/daemon/time_units.hpp"

namespace lidartag::daemon {

namespace {

// LCM 1.3.1 (Linux) sends "channel\0payload" above this many bytes in fragments.
constexpr size_t kLcmShortMessageMax = 65499;

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

LcmBus::LcmBus(const std::string& url) : url_(parse_lcm_url(url)) {
  check_multicast_route(url_);
  multicast_ = url_.provider == "udpm" || url_.provider == "mpudpm";
  if (url_.provider == "file") {
    log_ = std::make_unique<LcmLogWriter>(url_.target, url_.option("mode") == "a");
    lcm_ = std::make_unique<lcm::LCM>("memq://");
  } else {
    lcm_ = std::make_unique<lcm::LCM>(url_.text);
  }
  if (!lcm_->good()) {
    throw LcmError("cannot open LCM with URL '" + url_.text + "' (see LCM's message above)");
  }
}

LcmBus::~LcmBus() = default;

bool LcmBus::send(const std::string& channel, size_t size) {
  if (log_) {
    std::string why;
    if (!log_->write(channel, buffer_.data(), size, wall_utime(), why)) {
      failed(channel, std::move(why));
      return false;
    }
  } else {
    errno = 0;
    const int rc = lcm_->publish(channel, buffer_.data(), static_cast<unsigned>(size));
    const int error = errno;
    const bool fragments = multicast_ && channel.size() + 1 + size > kLcmShortMessageMax;
    if (rc != 0 || (fragments && error != 0)) {
      failed(channel, fmt::format("LCM publish of {} bytes{} failed: {}", size,
                                  fragments ? " (in fragments)" : "",
                                  error != 0 ? std::strerror(error) : "LCM reported an error"));
      return false;
    }
  }
  ++published_;
  if (failing_) {
    const int64_t now = now_ns();
    if (now >= next_report_ns_) {
      spdlog::info("LCM: delivering again ({} more message{} lost before; {} in all)", unreported_,
                   unreported_ == 1 ? "" : "s", failures_);
      failing_ = false;
      unreported_ = 0;
      next_report_ns_ = now + nanoseconds(kReportPeriodS);
    }
  }
  return true;
}

void LcmBus::failed(const std::string& channel, std::string why) {
  ++failures_;
  ++unreported_;
  last_error_ = channel + ": " + why;
  const int64_t now = now_ns();
  if (now < next_report_ns_) return;
  spdlog::warn("LCM: {} message{} not delivered ({} in all); last: {}", unreported_,
               unreported_ == 1 ? "" : "s", failures_, last_error_);
  unreported_ = 0;
  failing_ = true;
  next_report_ns_ = now + nanoseconds(kReportPeriodS);
}

uint64_t LcmBus::failures() const {
  std::lock_guard lock(mutex_);
  return failures_;
}

uint64_t LcmBus::published() const {
  std::lock_guard lock(mutex_);
  return published_;
}

std::string LcmBus::last_error() const {
  std::lock_guard lock(mutex_);
  return last_error_;
}

}  // namespace lidartag::daemon
