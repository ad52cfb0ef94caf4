#include "lidartag/daemon/health.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "lidartag/daemon/time_units.hpp"

namespace lidartag::daemon {

namespace {

// Most severe first: the state reported is the first problem's.
constexpr std::array<HealthState, 13> kSeverity = {
    HealthState::kError,          HealthState::kStalled,         HealthState::kNotDecoding,
    HealthState::kPublishFailing, HealthState::kModelMismatch,   HealthState::kSeveralSources,
    HealthState::kSilent,         HealthState::kRateImplausible, HealthState::kFallingBehind,
    HealthState::kPacketLoss,     HealthState::kTagSizeMismatch, HealthState::kWaiting,
    HealthState::kHealthy};

size_t rank(HealthState s) {
  return static_cast<size_t>(std::find(kSeverity.begin(), kSeverity.end(), s) - kSeverity.begin());
}

}  // namespace

std::string_view health_state_name(HealthState state) {
  switch (state) {
    case HealthState::kHealthy:
      return "healthy";
    case HealthState::kWaiting:
      return "waiting";
    case HealthState::kSilent:
      return "silent";
    case HealthState::kModelMismatch:
      return "model mismatch";
    case HealthState::kSeveralSources:
      return "several sources";
    case HealthState::kRateImplausible:
      return "rate implausible";
    case HealthState::kPacketLoss:
      return "packet loss";
    case HealthState::kFallingBehind:
      return "falling behind";
    case HealthState::kPublishFailing:
      return "publish failing";
    case HealthState::kStalled:
      return "stalled";
    case HealthState::kError:
      return "error";
    case HealthState::kEnded:
      return "ended";
    case HealthState::kNotDecoding:
      return "not decoding";
    case HealthState::kTagSizeMismatch:
      return "tag size mismatch";
  }
  return "unknown";
}

std::string ipv4_text(uint32_t a) {
  return fmt::format("{}.{}.{}.{}", a >> 24, (a >> 16) & 0xff, (a >> 8) & 0xff, a & 0xff);
}

void HealthMonitor::judge_window(const HealthSample& from, const HealthSample& to) {
  window_problems_.clear();
  const double dt = seconds(to.now_ns - from.now_ns);
  const uint64_t failures = to.publish_failures - from.publish_failures;
  if (failures > 0) {
    window_problems_.push_back({HealthState::kPublishFailing,
                                fmt::format("{} LCM message{} not published in the last {:.1f} s",
                                            failures, failures == 1 ? "" : "s", dt)});
  }
  const uint64_t mismatched = to.model_mismatch - from.model_mismatch;
  if (mismatched > 0) {
    window_problems_.push_back(
        {HealthState::kModelMismatch,
         to.model_note.empty()
             ? fmt::format("{} data packets in the last {:.1f} s do not fit the model decoded "
                           "(another sensor model on port {}?)",
                           mismatched, dt, to.data_port)
             : fmt::format("{} data packets in the last {:.1f} s do not fit the model decoded: {}",
                           mismatched, dt, to.model_note)});
  }
  const uint64_t decoded = to.decoded - from.decoded;
  const uint64_t rotations = to.rotations - from.rotations;
  const uint64_t arrived = to.data_packets - from.data_packets;
  if (arrived > 0 && decoded == 0) {
    // Progress, not flags: packets that arrive and are not decoded are a blind sensor, whatever
    // else holds (junk before the sensor, another sensor model, a wrong port).
    window_problems_.push_back(
        {HealthState::kNotDecoding,
         fmt::format("{} data packets on port {} in the last {:.1f} s, none decoded ({} "
                     "malformed in all){}{}",
                     arrived, to.data_port, dt, to.malformed, to.model_note.empty() ? "" : ": ",
                     to.model_note)});
  }
  if (decoded > 0) {
    // Rotations per second of the sensor's own time (a replay runs at any speed; a loop seam
    // sets the clock back: no verdict on that window).
    const double sensor_dt = seconds(to.sensor_ns - from.sensor_ns);
    const double per_second = sensor_dt > 0 ? static_cast<double>(rotations) / sensor_dt : 0.0;
    if (to.rpm > 0 && (to.rpm < options_.min_rpm || to.rpm > options_.max_rpm)) {
      window_problems_.push_back({HealthState::kRateImplausible,
                                  fmt::format("measured {:.0f} rpm, outside {:.0f}..{:.0f} rpm",
                                              to.rpm, options_.min_rpm, options_.max_rpm)});
    } else if (to.rpm > 0 && sensor_dt > 0 &&
               per_second > options_.max_rotation_ratio * to.rpm / 60.0 + 1.0 / sensor_dt) {
      window_problems_.push_back(
          {HealthState::kRateImplausible,
           fmt::format("{:.1f} rotations/s at {:.0f} rpm ({:.1f}/s expected): stray or spoofed "
                       "packets are cutting the stream",
                       per_second, to.rpm, to.rpm / 60.0)});
    } else if (rotations == 0 && dt > 60.0 / options_.min_rpm) {
      window_problems_.push_back(
          {HealthState::kRateImplausible,
           fmt::format("{} data packets but no rotation ended in the last {:.1f} s", decoded, dt)});
    }
  }
  const uint64_t stray = to.inconsistent - from.inconsistent;
  if (stray > 0 &&
      static_cast<double>(stray) > options_.max_loss * static_cast<double>(decoded + stray)) {
    window_problems_.push_back(
        {HealthState::kSeveralSources,
         fmt::format("{} data packets in the last {:.1f} s with azimuths that contradict the "
                     "stream (spoofed, or another sensor on port {}), dropped",
                     stray, dt, to.data_port)});
  }
  const uint64_t behind = to.dropped_behind - from.dropped_behind;
  if (behind > 0) {
    window_problems_.push_back(
        {HealthState::kFallingBehind,
         fmt::format("{} rotation{} dropped in the last {:.1f} s: detection is slower than the "
                     "sensor (more workers, or a lighter detector)",
                     behind, behind == 1 ? "" : "s", dt)});
  }
  const uint64_t misfits = to.size_warnings - from.size_warnings;
  if (misfits > 0) {
    // The configured size is wrong: every pose of that tag is biased (the size check).
    window_problems_.push_back(
        {HealthState::kTagSizeMismatch,
         fmt::format("{} detection{} in the last {:.1f} s measure another size than configured: "
                     "{}; configure the measured size (the printed marker's outer size)",
                     misfits, misfits == 1 ? "" : "s", dt, to.size_note)});
  }
  const uint64_t missing = to.missing - from.missing;
  const uint64_t expected = decoded + missing;
  if (expected >= 100 &&
      static_cast<double>(missing) > options_.max_loss * static_cast<double>(expected)) {
    window_problems_.push_back(
        {HealthState::kPacketLoss,
         fmt::format("{:.1f} % of the data packets missing in the last {:.1f} s ({} of {})",
                     100.0 * static_cast<double>(missing) / static_cast<double>(expected), dt,
                     missing, expected)});
  }
}

// The final status: "the source ended", then what went wrong over the whole run (a replay of
// another model's packets must not end looking like a clean one).
std::string HealthMonitor::ended_reason(const HealthSample& s) const {
  std::string reason = s.stopped ? "stopped" : "the source ended";
  const auto add = [&](const std::string& problem) { reason += "; " + problem; };
  if (!s.source_error.empty()) add(s.source_error);
  if (s.data_packets == 0) {
    // Say what came instead, so that a replay of the wrong file, port or a corrupt one does not
    // end looking like a quiet sensor.
    std::string instead;
    const auto note = [&](uint64_t n, const char* what) {
      if (n > 0) instead += fmt::format("{}{} {}", instead.empty() ? ": " : ", ", n, what);
    };
    note(s.malformed, "malformed or cut short");
    note(s.ignored, "on other ports or not IPv4/UDP");
    note(s.foreign, "from other senders");
    add(fmt::format("no data packet on port {}{}", s.data_port, instead));
  } else if (s.decoded == 0) {
    add(fmt::format(
        "none of its {} data packets could be decoded (another sensor model or vendor, or "
        "not LiDAR data?)",
        s.data_packets));
  }
  if (!s.model_problem.empty()) add(s.model_problem);
  if (s.model_mismatch > 0) {
    add(fmt::format("{} data packets did not fit the model decoded{}{}", s.model_mismatch,
                    s.model_note.empty() ? "" : ": ", s.model_note));
  }
  if (s.publish_failures > 0) add(fmt::format("{} LCM messages not published", s.publish_failures));
  if (s.size_warnings > 0) {
    add(fmt::format("{} detection{} measured another size than configured: {}", s.size_warnings,
                    s.size_warnings == 1 ? "" : "s", s.size_note));
  }
  if (s.dropped_behind > 0) {
    add(fmt::format("{} rotation{} dropped: detection was slower than the source", s.dropped_behind,
                    s.dropped_behind == 1 ? "" : "s"));
  }
  const uint64_t expected = s.decoded + s.missing;
  if (expected >= 100 &&
      static_cast<double>(s.missing) > options_.max_loss * static_cast<double>(expected)) {
    add(fmt::format("{:.1f} % of the data packets missing ({} of {})",
                    100.0 * static_cast<double>(s.missing) / static_cast<double>(expected),
                    s.missing, expected));
  }
  if (s.inconsistent > 0 &&
      static_cast<double>(s.inconsistent) >
          options_.max_loss * static_cast<double>(s.decoded + s.inconsistent)) {
    add(fmt::format("{} data packets with azimuths that contradict the stream, dropped",
                    s.inconsistent));
  }
  return reason;
}

Health HealthMonitor::update(const HealthSample& s) {
  if (s.ended) {
    if (!s.error.empty()) return {HealthState::kError, s.error};
    return {HealthState::kEnded, ended_reason(s)};
  }
  if (!have_window_) {
    window_start_ = s;
    have_window_ = true;
  } else if (seconds(s.now_ns - window_start_.now_ns) >= options_.window_s) {
    judge_window(window_start_, s);
    window_start_ = s;
  }

  std::vector<Problem> problems;
  if (!s.error.empty()) problems.push_back({HealthState::kError, s.error});
  if (!s.stall.empty()) problems.push_back({HealthState::kStalled, s.stall});
  problems.insert(problems.end(), window_problems_.begin(), window_problems_.end());
  if (!s.model_problem.empty()) problems.push_back({HealthState::kModelMismatch, s.model_problem});
  if (s.senders.size() > 1) {
    std::string list;
    for (uint32_t a : s.senders) list += (list.empty() ? "" : ", ") + ipv4_text(a);
    problems.push_back(
        {HealthState::kSeveralSources,
         fmt::format("data packets from {} on port {}: set sensors[].source.sensor_address to "
                     "one of them (one sensor entry per address, each with share_port)",
                     list, s.data_port)});
  }
  if (s.data_packets == 0) {
    const double since_start = seconds(s.now_ns - s.started_ns);
    if (since_start <= options_.startup_grace_s) {
      problems.push_back({HealthState::kWaiting,
                          fmt::format("waiting for packets on port {} ({:.0f} s since the start)",
                                      s.data_port, since_start)});
    } else {
      problems.push_back({HealthState::kSilent,
                          fmt::format("no packets on port {} in the {:.0f} s since the start",
                                      s.data_port, since_start)});
    }
  } else if (seconds(s.now_ns - s.last_data_ns) > options_.silence_s) {
    problems.push_back(
        {HealthState::kSilent, fmt::format("no packets on port {} for {:.1f} s (sensor silent)",
                                           s.data_port, seconds(s.now_ns - s.last_data_ns))});
  }

  if (problems.empty()) return {HealthState::kHealthy, ""};
  std::stable_sort(problems.begin(), problems.end(), [](const Problem& a, const Problem& b) {
    return rank(a.state) < rank(b.state);
  });
  Health h{problems.front().state, ""};
  for (const Problem& p : problems) {
    if (!h.reason.empty()) h.reason += "; ";
    h.reason += p.reason;
  }
  return h;
}

}  // namespace lidartag::daemon
