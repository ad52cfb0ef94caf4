// lidartagd's orchestration: the LCM bus, the shared oneTBB arena, one SensorPipeline per sensor,
// the status heartbeat, the systemd notifications and the signals. main() parses the command line
// and the configuration, blocks the signals, builds a Daemon and runs it.
#pragma once

#include <tbb/global_control.h>

#include <csignal>
#include <cstdio>
#include <functional>
#include <memory>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/ego_motion_input.hpp"
#include "lidartag/daemon/lcm_bus.hpp"
#include "lidartag/daemon/logging.hpp"
#include "lidartag/daemon/mcap_recorder.hpp"
#include "lidartag/daemon/notifier.hpp"
#include "lidartag/daemon/sensor_pipeline.hpp"
#include "lidartag/status_t.hpp"

namespace lidartag::daemon {

// Blocks SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGUSR1 and SIGUSR2 in the calling thread and in every
// thread it starts later (call first in main); Daemon::run() takes them with sigtimedwait. A
// blocked SIGPIPE makes a write to a closed pipe fail with EPIPE instead of killing the process.
void block_signals();

struct RunOptions {
  std::FILE* print_detections = nullptr;  // one line per rotation, or null
  // Test seam (not on the command line): called before each rotation's detection, e.g. to stall
  // the pipeline in the watchdog test.
  SensorPipeline::DetectHook detect_hook;
  // On SIGHUP, after the log is reopened: reads the configuration again and says how it compares
  // with the running one (empty: unchanged). The daemon logs what it returns: a configuration
  // that no longer loads, or edits that need a restart, are never ignored silently.
  std::function<std::string()> reload_check;
};

class Daemon {
 public:
  // Opens everything (LCM, sources, calibrations, detectors, the --record file): setup errors
  // throw here, before READY=1. `logging` may be null (no SIGHUP reopen).
  Daemon(DaemonOptions options, RunOptions run, Logging* logging);
  ~Daemon();

  // Runs until SIGINT/SIGTERM or until every source has ended (replays). Returns the exit
  // status: 0, or 1 when a pipeline stopped on an error.
  int run();

  int workers() const { return workers_; }
  // For main's exit status (daemon-setup): messages not delivered, an incomplete --record file.
  const LcmBus& bus() const { return *bus_; }
  const PcapRecorder* recorder() const { return recorder_.get(); }
  const McapRecorder* mcap() const { return mcap_.get(); }
  // Sources that ended before their end (a replay cut short by a corrupt record): data lost.
  size_t sources_cut_short() const;

 private:
  void publish_status(bool final);
  std::string summary() const;
  bool progressing() const;

  DaemonOptions options_;
  Logging* logging_;
  std::function<std::string()> reload_check_;
  int workers_;
  Notifier notifier_;
  std::unique_ptr<LcmBus> bus_;
  std::unique_ptr<EgoMotionInput> ego_;  // ego_motion.channel set; outlives the pipelines
  std::unique_ptr<tbb::global_control> threads_;
  std::unique_ptr<tbb::task_arena> arena_;
  std::unique_ptr<PcapRecorder> recorder_;
  std::unique_ptr<McapRecorder> mcap_;
  std::unique_ptr<LinePrinter> printer_;
  std::vector<std::unique_ptr<SensorPipeline>> pipelines_;
  std::vector<SensorStatus> last_status_;
  lidartag::status_t status_message_;
  int64_t started_ns_ = 0;
};

}  // namespace lidartag::daemon
