// A sensor's health: what its counters and clocks say, against what the sensor should deliver.
// One state (the most severe problem) and a reason naming every problem, for status_t and the
// systemd STATUS= line. Pure logic over samples (no threads, no LCM): tested on its own.
// docs/daemon.md, "Health", says what each state means and which option sets its threshold.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/daemon/config.hpp"

namespace lidartag::daemon {

// Values of status_t.state (lcmtypes/status_t.lcm has the same numbers).
enum class HealthState : uint8_t {
  kHealthy = 0,          // packets arrive, rotations complete at the sensor's rate, publishes work
  kWaiting = 1,          // no packet yet, within health.startup_grace_s of the start
  kSilent = 2,           // no packet for health.silence_s (or none since a start past the grace)
  kModelMismatch = 3,    // the model decoded does not fit the packets (configured, or mid-stream)
  kSeveralSources = 4,   // data packets from more than one sender address
  kRateImplausible = 5,  // rotations per second or rpm impossible for the sensor
  kPacketLoss = 6,       // data packets missing above health.max_loss
  kFallingBehind = 7,    // rotations dropped because detection is slower than the sensor
  kPublishFailing = 8,   // LCM messages could not be published
  kStalled = 9,          // the receiver or the detection pipeline made no progress
  kError = 10,           // the pipeline stopped on an error
  kEnded = 11,  // the source ended (replay done, or stopped) and everything was published; the
                // reason adds what went wrong over the whole run
  kNotDecoding = 12,  // data packets arrive but none was decoded over a whole window
  // tags found whose points measure another size than the configured one (a biased pose)
  kTagSizeMismatch = 13,
};
std::string_view health_state_name(HealthState state);

// What the pipeline knows at one moment. Times are steady-clock ns.
struct HealthSample {
  int64_t now_ns = 0;
  int64_t started_ns = 0;
  bool ended = false;    // the source ended and every rotation was published
  bool stopped = false;  // ended because the daemon was stopped (a signal), not by the source
  // Why the source ended before its end (a replay cut short by a corrupt record); else empty.
  std::string source_error;
  std::string error;  // why the pipeline stopped, if it did
  std::string stall;  // why the pipeline makes no progress (see SensorPipeline); empty if it does
  uint16_t data_port = 0;
  uint64_t data_packets = 0;    // data packets received
  int64_t last_data_ns = 0;     // when the last one was; 0: none yet
  uint64_t decoded = 0;         // data packets decoded
  uint64_t malformed = 0;       // status_t's packets_malformed
  uint64_t ignored = 0;         // other traffic: other ports, not IPv4/UDP
  uint64_t foreign = 0;         // to the sensor's ports from another sender, ignored
  uint64_t missing = 0;         // data packets missing from the stream (sequence gaps)
  uint64_t model_mismatch = 0;  // data packets contradicting the model in use
  uint64_t inconsistent = 0;    // data packets whose azimuth contradicts the stream (dropped)
  uint64_t rotations = 0;       // rotations assembled
  // The sensor's clock at the last rotation assembled (its first firing): rotations per second
  // are judged on it, so that replays at any speed are judged as the sensor ran.
  int64_t sensor_ns = 0;
  uint64_t dropped_behind = 0;    // rotations dropped because detection fell behind
  uint64_t publish_failures = 0;  // LCM messages of this sensor (or the bus) not published
  double rpm = 0;                 // measured by the last rotation; 0: not known
  std::string model_problem;      // the model decoded does not fit the packets; empty if it does
  std::string model_note;  // the capture reader's own account (CaptureReader::model_mismatch())
  std::vector<uint32_t> senders;  // distinct data-packet sender addresses seen lately
  // Detections whose measured size contradicts the configured one (Detection::size_warning),
  // and the latest of them ("tag16h5 id 3 measures 0.800 m, configured 0.750 m").
  uint64_t size_warnings = 0;
  std::string size_note;
};

struct Health {
  HealthState state = HealthState::kWaiting;
  std::string reason;  // every problem, most severe first; empty when healthy
  bool healthy() const { return state == HealthState::kHealthy; }
};

class HealthMonitor {
 public:
  explicit HealthMonitor(HealthOptions options) : options_(options) {}
  // Judges `sample`; rates (loss, rotations per second, drops, publish failures) over the last
  // window of health.window_s, whose verdict holds until the next window closes.
  Health update(const HealthSample& sample);

 private:
  struct Problem {
    HealthState state;
    std::string reason;
  };
  void judge_window(const HealthSample& from, const HealthSample& to);
  std::string ended_reason(const HealthSample& s) const;

  HealthOptions options_;
  HealthSample window_start_;
  bool have_window_ = false;
  std::vector<Problem> window_problems_;
};

// "a.b.c.d" of a host-order IPv4 address.
std::string ipv4_text(uint32_t address);

}  // namespace lidartag::daemon
