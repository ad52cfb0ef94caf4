#include "lidartag/daemon/daemon.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <ctime>
#include <thread>

#include "lidartag/daemon/messages.hpp"

namespace lidartag::daemon {

namespace {

sigset_t handled_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGHUP);
  // daemon-setup: SIGPIPE (writes to a closed pipe fail with EPIPE instead of killing; the
  // --print-detections printer raises it to stop the daemon), SIGUSR1 (status now), SIGUSR2.
  sigaddset(&set, SIGPIPE);
  sigaddset(&set, SIGUSR1);
  sigaddset(&set, SIGUSR2);
  // SIGQUIT stops like SIGTERM (with the final status, no core); SIGALRM is ignored (noted).
  sigaddset(&set, SIGQUIT);
  sigaddset(&set, SIGALRM);
  return set;
}

// At most one action and log line per signal kind a second: a flood of signals (any local
// process of the same user can send them) must not fill the disk with logs and status messages.
class SignalLimiter {
 public:
  // True when `sig` may act now; else counted (the next line that acts says how many were
  // skipped, via skipped()).
  bool allow(int sig, std::chrono::steady_clock::time_point now) {
    Entry& e = entries_[static_cast<size_t>(sig) % entries_.size()];
    if (now < e.next) {
      ++e.skipped;
      return false;
    }
    e.next = now + std::chrono::seconds(1);
    last_skipped_ = e.skipped;
    e.skipped = 0;
    return true;
  }
  // What allow() skipped of the signal it last allowed, for its log line.
  std::string skipped() const {
    return last_skipped_ == 0
               ? std::string()
               : fmt::format(" ({} more in the last second, not acted on)", last_skipped_);
  }

 private:
  struct Entry {
    std::chrono::steady_clock::time_point next{};
    uint64_t skipped = 0;
  };
  std::array<Entry, 65> entries_{};
  uint64_t last_skipped_ = 0;
};

}  // namespace

void block_signals() {
  const sigset_t set = handled_signals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

Daemon::Daemon(DaemonOptions options, RunOptions run, Logging* logging)
    : options_(std::move(options)), logging_(logging), reload_check_(std::move(run.reload_check)) {
  workers_ = options_.pipeline.worker_threads > 0
                 ? options_.pipeline.worker_threads
                 : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  // The arena's threads are all workers (no slot kept for a master thread: the receivers only
  // hand tasks to it), and the global limit must allow that many beside the main thread.
  const auto limit = static_cast<size_t>(workers_ + 1);
  threads_ = std::make_unique<tbb::global_control>(
      tbb::global_control::max_allowed_parallelism,
      std::max(limit,
               tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  arena_ = std::make_unique<tbb::task_arena>(workers_, 0);
  bus_ = std::make_unique<LcmBus>(options_.lcm.url);
  if (!options_.ego_motion.channel.empty()) {
    ego_ = std::make_unique<EgoMotionInput>(options_.ego_motion, options_.lcm.url,
                                            sensor_mounts(options_));
    bus_->attach_ego_motion(ego_.get());
  }
  if (!options_.record_pcap.empty()) {
    recorder_ = std::make_unique<PcapRecorder>(options_.record_pcap);
  }
  if (!options_.mcap.empty()) mcap_ = std::make_unique<McapRecorder>(options_.mcap);
  if (run.print_detections != nullptr) {
    printer_ = std::make_unique<LinePrinter>(run.print_detections);
  }
  for (const auto& sensor : options_.sensors) {
    pipelines_.push_back(std::make_unique<SensorPipeline>(sensor, options_, *bus_, *arena_,
                                                          workers_, recorder_.get(), printer_.get(),
                                                          run.detect_hook));
    pipelines_.back()->record_mcap(mcap_.get());
  }
}

Daemon::~Daemon() {
  for (auto& p : pipelines_) p->stop();
  for (auto& p : pipelines_) p->join();
}

bool Daemon::progressing() const {
  const int64_t now = steady_ns();
  return std::all_of(pipelines_.begin(), pipelines_.end(),
                     [&](const auto& p) { return p->progressing(now); });
}

size_t Daemon::sources_cut_short() const {
  return static_cast<size_t>(std::count_if(pipelines_.begin(), pipelines_.end(), [](const auto& p) {
    return !p->source_error().empty();
  }));
}

std::string Daemon::summary() const {
  std::string text;
  for (const auto& s : last_status_) {
    if (!text.empty()) text += "; ";
    // The partial rotations at a --loop seam are not losses: named apart from the dropped ones.
    const std::string seam = s.rotations_seam == 0
                                 ? std::string()
                                 : fmt::format(", {} loop-seam partial{} (not published by design)",
                                               s.rotations_seam, s.rotations_seam == 1 ? "" : "s");
    text += fmt::format("{}: {} {} rotations published, {} dropped{}, {} tags, {}{}{}", s.sensor,
                        s.model.empty() ? "(model unknown)" : s.model, s.rotations_published,
                        s.rotations_behind + s.rotations_unsent, seam, s.detections,
                        health_state_name(s.health.state), s.health.reason.empty() ? "" : " (",
                        s.health.reason.empty() ? "" : s.health.reason + ")");
  }
  if (ego_) {
    const std::string note = ego_->health_note();
    if (!note.empty()) text += "; " + note;
  }
  return text;
}

void Daemon::publish_status(bool final) {
  const int64_t now = steady_ns();
  const double uptime = static_cast<double>(now - started_ns_) * 1e-9;
  last_status_.clear();
  std::optional<EgoMotionState> ego;
  if (ego_) ego = ego_->state();
  for (auto& p : pipelines_) {
    SensorStatus s = p->status(now);
    fill_status(s, wall_utime(), uptime, status_message_);
    fill_ego_status(ego ? &*ego : nullptr, status_message_);
    if (ego_) {
      // The ego-motion input's note (nothing yet, stale, dropped messages): the trackers run
      // without it meanwhile, which is no fault of the sensor (its health stays as it is).
      const std::string note = ego_->health_note();
      if (!note.empty())
        status_message_.reason += (status_message_.reason.empty() ? "" : "; ") + note;
    }
    bus_->publish(channel_of(p->sensor(), options_.lcm.channels.status), status_message_);
    if (mcap_) mcap_->status(s);
    last_status_.push_back(std::move(s));
  }
  const std::string text = summary();
  if (final) {
    spdlog::info("final status: {}", text);
  } else {
    notifier_.status(text);
    spdlog::debug("status: {}", text);
  }
}

int Daemon::run() {
  started_ns_ = steady_ns();
  if (ego_) {
    ego_->start();
    spdlog::info("ego motion: receiving {} (the trackers place tags in its odometry frame)",
                 ego_->channel());
  }
  for (auto& p : pipelines_) p->start();
  for (const auto& s : options_.sensors) {
    spdlog::info("sensor {}: {} source{}{}, frame {}, channels {}*", s.name,
                 source_kind_name(s.source.kind), s.source.file.empty() ? "" : " ", s.source.file,
                 s.frame_id, s.channel_prefix + "LIDARTAG_");
  }
  spdlog::info("running: {} sensor(s), {} detector thread(s), LCM {}", pipelines_.size(), workers_,
               options_.lcm.url.empty() ? "(default URL)" : options_.lcm.url);
  notifier_.ready(fmt::format("running: {} sensor(s)", pipelines_.size()));

  using Clock = std::chrono::steady_clock;
  const auto status_period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.status.period_s));
  const auto ping = notifier_.ping_interval();
  if (ping) {
    spdlog::info("systemd watchdog: pinging every {} ms while every sensor progresses",
                 std::chrono::duration_cast<std::chrono::milliseconds>(*ping).count());
  }
  auto next_status = Clock::now() + status_period;
  auto next_ping = Clock::now();
  bool was_progressing = true;
  const sigset_t signals = handled_signals();
  int stop_signal = 0;
  bool sigpipe_noted = false;
  SignalLimiter limiter;

  for (;;) {
    const auto now = Clock::now();
    if (ping && now >= next_ping) {
      // Fed only by progress: a stuck pipeline, or a sensor silent past the grace, lets
      // WatchdogSec run out and systemd restart the daemon.
      const bool ok = progressing();
      if (ok) notifier_.watchdog();
      if (ok != was_progressing) {
        if (ok) {
          spdlog::warn("every sensor progresses again: watchdog pings resumed");
        } else {
          publish_status(false);  // says which sensor and why
          spdlog::warn("no progress: watchdog pings suspended ({})", summary());
        }
      }
      was_progressing = ok;
      next_ping = now + *ping;
    }
    if (now >= next_status) {
      publish_status(false);
      next_status = now + status_period;
    }
    if (std::all_of(pipelines_.begin(), pipelines_.end(),
                    [](const auto& p) { return p->finished(); })) {
      break;
    }
    // Sleep until the next duty or a signal, at most 100 ms (to notice finished replays).
    auto wake = std::min(next_status, now + std::chrono::milliseconds(100));
    if (ping) wake = std::min(wake, next_ping);
    const auto wait = std::max<Clock::duration>(wake - Clock::now(), Clock::duration::zero());
    const auto wait_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count();
    timespec ts{static_cast<time_t>(wait_ns / 1000000000), static_cast<long>(wait_ns % 1000000000)};
    const int sig = sigtimedwait(&signals, nullptr, &ts);
    const bool repeatable = sig == SIGHUP || sig == SIGUSR1 || sig == SIGUSR2 || sig == SIGALRM;
    if (repeatable && !limiter.allow(sig, Clock::now())) continue;
    if (sig == SIGHUP) {
      spdlog::info("SIGHUP: reopening the log{}", limiter.skipped());
      if (logging_ != nullptr) {
        try {
          logging_->reopen();
        } catch (const std::exception& e) {
          spdlog::error("cannot reopen the log: {}", e.what());
        }
      }
      if (reload_check_) {
        const std::string verdict = reload_check_();
        if (!verdict.empty()) spdlog::warn("SIGHUP: {}", verdict);
      }
    } else if (sig == SIGINT || sig == SIGTERM || sig == SIGQUIT) {
      stop_signal = sig;
      break;
    } else if (sig == SIGPIPE) {
      // daemon-setup: the reader of --print-detections went away: stop as on SIGTERM. Another
      // closed pipe or socket (e.g. a log reader) is no reason to stop: noted once.
      if (printer_ && printer_->closed()) {
        stop_signal = sig;
        break;
      }
      if (!sigpipe_noted) spdlog::warn("SIGPIPE: a write to a closed pipe or socket; ignored");
      sigpipe_noted = true;
    } else if (sig == SIGUSR1) {
      publish_status(false);
      spdlog::info("SIGUSR1: status: {}{}", summary(), limiter.skipped());
    } else if (sig == SIGUSR2 || sig == SIGALRM) {
      spdlog::info("{}: ignored (no action is bound to it){}",
                   sig == SIGUSR2 ? "SIGUSR2" : "SIGALRM", limiter.skipped());
    }
  }

  if (stop_signal != 0) {
    spdlog::info("{}: stopping", stop_signal == SIGINT    ? "SIGINT"
                                 : stop_signal == SIGTERM ? "SIGTERM"
                                 : stop_signal == SIGQUIT ? "SIGQUIT"
                                                          : "SIGPIPE (standard output closed)");
  } else {
    spdlog::info("every source ended: stopping");
  }
  notifier_.stopping("stopping");
  for (auto& p : pipelines_) p->stop();
  for (auto& p : pipelines_) p->join();
  publish_status(true);
  if (mcap_) mcap_->close();
  if (recorder_) {
    recorder_->close();
    if (!recorder_->error().empty()) {
      spdlog::error("recording {} failed: {}", options_.record_pcap, recorder_->error());
    } else {
      spdlog::info("recorded {} packets to {}", recorder_->records(), options_.record_pcap);
    }
  }
  int status = 0;
  for (const auto& p : pipelines_) {
    if (!p->error().empty()) status = 1;
  }
  if (logging_ != nullptr) logging_->flush();
  return status;
}

}  // namespace lidartag::daemon
