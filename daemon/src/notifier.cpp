#include "lidartag/daemon/notifier.hpp"

#include <systemd/sd-daemon.h>

namespace lidartag::daemon {

namespace {

// Status text on one line (the protocol is newline-separated assignments).
std::string one_line(std::string text) {
  for (char& c : text) {
    if (c == '\n') c = ' ';
  }
  return text;
}

}  // namespace

Notifier::Notifier() {
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdog_ = std::chrono::microseconds(static_cast<std::chrono::microseconds::rep>(usec));
  }
}

std::optional<std::chrono::microseconds> Notifier::ping_interval() const {
  if (!watchdog_) return std::nullopt;
  return *watchdog_ / 2;
}

void Notifier::ready(const std::string& status) const {
  sd_notify(0, ("READY=1\nSTATUS=" + one_line(status)).c_str());
}

void Notifier::status(const std::string& status) const {
  sd_notify(0, ("STATUS=" + one_line(status)).c_str());
}

void Notifier::watchdog() const {
  sd_notify(0, "WATCHDOG=1");
}

void Notifier::stopping(const std::string& status) const {
  sd_notify(0, ("STOPPING=1\nSTATUS=" + one_line(status)).c_str());
}

}  // namespace lidartag::daemon
