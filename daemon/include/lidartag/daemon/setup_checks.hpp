// Everything lidartagd will open, checked in one place before the daemon is built, so that a
// setup problem stops it before READY=1 with one line naming the setting, instead of surfacing
// later (a calibration file read only when the first packet decides the model) or not at all (a
// second daemon on a sensor's port). The resources are opened for real afterwards, still before
// READY=1, and those constructors fail cleanly too; these checks give the clearer message.
#pragma once

#include <stdexcept>
#include <string>

#include "lidartag/daemon/config.hpp"

namespace lidartag::daemon {

// A resource of the configuration cannot be used. what(): "KEY: PROBLEM", one line, e.g.
// "sensors[0].calibration: calibration file '/x.yaml': no such file".
class SetupError : public std::runtime_error {
 public:
  SetupError(const std::string& key, const std::string& problem);
  const std::string& key() const { return key_; }

 private:
  std::string key_;
};

// A calibration file larger than this is refused (real ones are 5 to 30 kB).
inline constexpr size_t kMaxCalibrationBytes = size_t{1} << 20;

// Throws SetupError on the first problem (ConfigError for logging.file), in this order:
// - lcm.url: the URL (parse_lcm_url), the multicast route (check_multicast_route), for file://
//   a log that can be created: not a symbolic link, FIFO, socket or block device;
// - record_pcap: a file that can be created (its directory exists and is writable), not a
//   symbolic link, FIFO, socket or block device, and not a file a sensor replays;
// - logging.file: not a FIFO that nobody reads, not a file a sensor replays;
// - lcm.url's file: not a file a sensor replays;
// - per sensor: the calibration file: a regular file of at most kMaxCalibrationBytes that parses
//   and fits the configured model, or with model auto fits at least one model; a replay file
//   that can be read (a FIFO: its writer there within 5 s); UDP ports that can be bound as the
//   source will bind them (exclusively unless share_port; a multicast group shares), and no two
//   sensors of this daemon on one port unless both share it.
void check_setup(const DaemonOptions& options);

}  // namespace lidartag::daemon
