// systemd's service notification protocol (sd_notify): READY=1 once the pipeline runs, STATUS=
// lines, WATCHDOG=1 pings, STOPPING=1. Without $NOTIFY_SOCKET every call is a no-op.
#pragma once

#include <chrono>
#include <optional>
#include <string>

namespace lidartag::daemon {

class Notifier {
 public:
  // Reads $WATCHDOG_USEC (and $WATCHDOG_PID) once.
  Notifier();
  // The interval the service manager expects pings at ($WATCHDOG_USEC); empty when disabled.
  std::optional<std::chrono::microseconds> watchdog_timeout() const { return watchdog_; }
  // How often to ping: half the timeout, as sd_watchdog_enabled(3) advises.
  std::optional<std::chrono::microseconds> ping_interval() const;

  void ready(const std::string& status) const;
  void status(const std::string& status) const;
  void watchdog() const;
  void stopping(const std::string& status) const;

 private:
  std::optional<std::chrono::microseconds> watchdog_;
};

}  // namespace lidartag::daemon
