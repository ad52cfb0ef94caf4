// lidartagd: the LiDARTag daemon. Reads the configuration, applies the command line, checks every
// resource it will open (setup_checks), runs the pipelines. Exit status: 0 normal end, 1 setup or
// runtime failure, 2 bad configuration or usage, 3 the run ended but data was lost (LCM messages
// not delivered, an incomplete --record file).
#include <spdlog/spdlog.h>

// CLI11 1.9's split() trips GCC 12's -Wnull-dereference once inlined here (a false positive inside
// libstdc++'s string); the project's own code below is still checked by every other warning.
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <exception>
#include <new>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include "lidartag/daemon/config.hpp"
#include "lidartag/daemon/daemon.hpp"
#include "lidartag/daemon/logging.hpp"
#include "lidartag/daemon/setup_checks.hpp"
#include "lidartag/driver/ouster/packet.hpp"
#include "lidartag/version.hpp"

namespace {

using lidartag::daemon::ConfigError;
using lidartag::daemon::DaemonOptions;
using lidartag::daemon::SourceKind;

struct Args {
  std::string config;
  std::vector<std::string> set;
  std::optional<std::string> lcm_url;
  std::string replay, replay_lcm, record, mcap, topic, metadata;
  std::optional<double> rate, start, duration;
  bool max_speed = false, loop = false;
  std::optional<int> workers;
  std::optional<std::string> log_level, log_file;
  bool print_config = false, print_detections = false;
};

// The command line's settings over the file's; checked again afterwards like the file's.
void apply(const Args& a, DaemonOptions& o) {
  if (a.lcm_url) o.lcm.url = *a.lcm_url;
  if (a.workers) o.pipeline.worker_threads = *a.workers;
  if (a.log_level) o.logging.level = *a.log_level;
  if (a.log_file) o.logging.file = *a.log_file;
  if (!a.record.empty()) o.record_pcap = a.record;
  if (!a.mcap.empty()) o.mcap = a.mcap;
  for (auto& sensor : o.sensors) {
    auto& src = sensor.source;
    if (!a.replay.empty()) {
      src.kind = SourceKind::kPcap;
      src.file = a.replay;
    } else if (!a.replay_lcm.empty()) {
      src.kind = SourceKind::kLcm;
      src.file = a.replay_lcm;
    }
    if (!a.topic.empty()) src.topic = a.topic;
    if (!a.metadata.empty()) {
      // An Ouster sensor: its own ports unless the configuration named others.
      sensor.metadata = a.metadata;
      if (src.data_port == lidartag::velodyne::kDefaultDataPort &&
          src.position_port == lidartag::velodyne::kDefaultPositionPort) {
        src.data_port = lidartag::driver::ouster::kLidarPort;
        src.position_port = lidartag::driver::ouster::kImuPort;
      }
    }
    if (a.max_speed) src.rate = 0.0;
    if (a.rate) src.rate = *a.rate;
    if (a.loop) src.loop = true;
    if (a.start) src.start = *a.start;
    if (a.duration) src.duration = *a.duration;
  }
  lidartag::daemon::validate(o);
}

int config_error(const std::string& message) {
  std::fprintf(stderr, "lidartagd: config error: %s\n", message.c_str());
  return 2;
}

// Exit statuses (docs/daemon.md).
constexpr int kExitSetupError = 1;
constexpr int kExitDataLost = 3;

int setup_error(const std::exception& e) {
  // One line whatever the message holds (paths and values come from the configuration). What the
  // system refused (a thread, memory) says which limit to look at: a bare "Resource temporarily
  // unavailable" does not.
  std::string what = e.what();
  if (const auto* s = dynamic_cast<const std::system_error*>(&e);
      s != nullptr && s->code() == std::errc::resource_unavailable_try_again) {
    what = "cannot start a thread (" + what +
           "): the process's limits (address space, RLIMIT_AS; threads, RLIMIT_NPROC) are too low";
  } else if (dynamic_cast<const std::bad_alloc*>(&e) != nullptr) {
    what = "out of memory while setting up (" + what +
           "): the address-space limit (RLIMIT_AS) "
           "or the machine's memory is too small for this configuration";
  }
  std::fprintf(stderr, "lidartagd: error: %s\n", lidartag::daemon::clip_text(what, 600).c_str());
  return kExitSetupError;
}

// SIGHUP's look at the configuration: the file read again with the same command line, compared
// with what runs. Only the log is reopened on SIGHUP; the rest needs a restart, and says so.
std::string reload_verdict(const Args& a, const std::string& running) {
  if (a.config.empty()) return {};
  try {
    DaemonOptions now = lidartag::daemon::load_config(a.config, a.set);
    apply(a, now);
    if (lidartag::daemon::print_config(now) == running) return {};
    return "the configuration '" + a.config +
           "' changed since the start; SIGHUP only reopens the log: restart the daemon "
           "(systemctl restart lidartagd) to apply it";
  } catch (const std::exception& e) {
    return "the configuration '" + a.config + "' no longer loads (" +
           lidartag::daemon::clip_text(e.what(), 400) + "); the running one is kept";
  }
}

// After a run: what did not reach its destination makes the exit status 3 (unless it is already
// an error), with one line for the LCM messages (the --record file's line is the daemon's own).
int data_loss_status(const lidartag::daemon::Daemon& daemon, int status) {
  const auto& bus = daemon.bus();
  const uint64_t failures = bus.failures();
  if (failures > 0) {
    spdlog::error("LCM: {} of {} messages were not delivered; last: {}", failures,
                  failures + bus.published(), bus.last_error());
  }
  const auto* recorder = daemon.recorder();
  const bool lost = failures > 0 || (recorder != nullptr && recorder->failed()) ||
                    (daemon.mcap() != nullptr && daemon.mcap()->failed()) ||
                    daemon.sources_cut_short() > 0;
  return status == 0 && lost ? kExitDataLost : status;
}

}  // namespace

int main(int argc, char** argv) {
  // First of all, so that a signal in the first milliseconds (before the configuration is read)
  // is handled by the run loop rather than killing the process; every thread inherits the mask.
  lidartag::daemon::block_signals();
  // A file-size limit (RLIMIT_FSIZE) makes writes past it fail with EFBIG, handled as any write
  // error (the recording cut back to its last whole packet, exit status 3), instead of killing.
  std::signal(SIGXFSZ, SIG_IGN);
  Args a;
  CLI::App app{
      "lidartagd: LiDARTag detection daemon. Receives Velodyne packets (live UDP, interface "
      "capture, pcap or LCM log replay), detects LiDARTags in every rotation and publishes them "
      "on LCM. See docs/daemon.md."};
  app.set_version_flag("--version", std::string("lidartagd ") + lidartag::kVersionString,
                       "Print the version and exit");
  app.add_option("-c,--config", a.config, "Configuration file (YAML; see config/lidartagd.yaml)");
  app.add_option("--set", a.set,
                 "Override one setting: KEY=VALUE (YAML value), repeatable, e.g. "
                 "--set detector.tag_sizes_m=[0.8] --set sensors[0].model=vlp32c");
  app.add_option("--lcm-url", a.lcm_url,
                 "LCM URL (default: the config's lcm.url, else LCM's default multicast URL); "
                 "e.g. file:///tmp/tags.lcmlog?mode=w writes a log instead of using the network");
  // Whether the file can be read is a setup check (exit 1, naming sensors[N].source.file), as for
  // a replay file named in the configuration.
  auto* replay = app.add_option(
      "--replay", a.replay,
      "Replay this capture for every sensor: a pcap or pcapng of Velodyne or Ouster packets "
      "(Ouster "
      "metadata from --metadata or NAME.json beside NAME.pcap), or a ROS 1 bag, ROS 2 bag or MCAP "
      "file of VelodyneScan or Ouster packet messages");
  app.add_option("--topic", a.topic,
                 "The LiDAR topic of a replayed bag (default: its one LiDAR topic)");
  app.add_option("--start", a.start,
                 "Replay from SECONDS after the capture's first packet (a bag: its earliest "
                 "message); what comes before is counted and passed over")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration", a.duration, "Replay SECONDS from --start only (default: to the end)")
      ->check(CLI::PositiveNumber);
  app.add_option("--metadata", a.metadata,
                 "Ouster sensor metadata JSON for every sensor (the sensor is then an Ouster; "
                 "ports 7502/7503 unless configured otherwise)");
  auto* replay_lcm =
      app.add_option("--replay-lcm", a.replay_lcm,
                     "Replay the raw packets of this LCM log (lcm-logger of the raw channel)");
  replay->excludes(replay_lcm);
  auto* rate = app.add_option("--rate", a.rate, "Replay speed factor (1 = recorded pace)")
                   ->check(CLI::PositiveNumber);
  app.add_flag("--max-speed", a.max_speed, "Replay as fast as the detector goes")->excludes(rate);
  app.add_flag("--loop", a.loop, "Replay in a loop");
  app.add_option("--record", a.record,
                 "Write every received packet to this pcap file (a write error, e.g. a full disk, "
                 "stops recording: exit status 3)");
  app.add_option("--mcap", a.mcap,
                 "Also write what is published (clouds when lcm.cloud_decimation > 0, tags, "
                 "detections, status) to this MCAP file for Foxglove (docs/foxglove.md; a write "
                 "error: exit status 3)");
  app.add_option("--workers", a.workers, "Detector threads (0: one per core)");
  app.add_option("--log-level", a.log_level, "trace, debug, info, warn, error, critical, off");
  app.add_option("--log-file", a.log_file, "Log to this file (reopened on SIGHUP)");
  app.add_flag("--print-config", a.print_config, "Print the effective configuration and exit");
  app.add_flag("--print-detections", a.print_detections,
               "Print each rotation's detections on standard output, one line per rotation "
               "(when its reader goes away, e.g. '| head -1', the daemon stops as on SIGTERM)");
  app.footer(
      "Exit status: 0 normal end (a signal, or every replay ended), 1 setup or runtime error "
      "(a file, port, calibration or LCM URL that cannot be used; checked before READY=1), 2 bad "
      "configuration or command line, 3 the run ended but data was lost (LCM messages not "
      "delivered, an incomplete --record file, a replay cut short by a corrupt record).\n"
      "Signals: SIGINT/SIGTERM/SIGQUIT stop cleanly (final status logged and published), SIGHUP "
      "reopens the log file (and warns when the configuration file changed or no longer loads: "
      "settings apply on restart), SIGUSR1 logs and publishes the status now, SIGUSR2 and SIGALRM "
      "are "
      "ignored (each acted on and logged at most once a second), SIGPIPE and SIGXFSZ do not "
      "kill it.");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Help and version exit 0; a usage error is one line with the program's prefix, exit 2.
    if (e.get_exit_code() == 0) return app.exit(e) == 0 ? 0 : 2;
    std::fprintf(stderr, "lidartagd: error: %s (run with --help for the options)\n", e.what());
    return 2;
  }

  DaemonOptions options;
  try {
    options = a.config.empty() ? lidartag::daemon::parse_config("", a.set)
                               : lidartag::daemon::load_config(a.config, a.set);
    apply(a, options);
  } catch (const ConfigError& e) {
    return config_error(e.what());
  }
  if (a.print_config) {
    std::fputs(lidartag::daemon::print_config(options).c_str(), stdout);
    return 0;
  }

  try {
    // Before READY=1 and before any thread: every file, port and URL the daemon will open.
    lidartag::daemon::check_setup(options);
    lidartag::daemon::Logging logging(options.logging);
    lidartag::daemon::RunOptions run;
    if (a.print_detections) run.print_detections = stdout;
    run.reload_check = [&a, running = lidartag::daemon::print_config(options)] {
      return reload_verdict(a, running);
    };
    lidartag::daemon::Daemon daemon(std::move(options), run, &logging);
    return data_loss_status(daemon, daemon.run());
  } catch (const ConfigError& e) {
    return config_error(e.what());
  } catch (const std::exception& e) {
    return setup_error(e);
  }
}
