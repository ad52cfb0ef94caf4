// A sensor pipeline's health and counters at one moment: what status_t and systemd's STATUS=
// report. Plain data, no LCM.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lidartag/daemon/health.hpp"
#include "lidartag/daemon/latency_window.hpp"

namespace lidartag::daemon {

// The ego-motion input's counters (EgoMotionInput; the same for every sensor).
// Messages received, each counted once: received = accepted + dropped(), and dropped() =
// out_of_order + invalid + unknown_kind + undecodable.
struct EgoMotionCounts {
  uint64_t received = 0, accepted = 0, out_of_order = 0, invalid = 0, unknown_kind = 0,
           undecodable = 0;
  // Accepted messages stamped more than ego_motion.max_gap_s after the previous accepted one:
  // no pose is interpolated across such a gap (twists start a new odometry frame there).
  uint64_t gaps = 0;
  // Times the channel went quiet for more than ego_motion.stale_s (host time) after a message.
  uint64_t stale_episodes = 0;
  uint64_t dropped() const { return out_of_order + invalid + unknown_kind + undecodable; }
};

// The input at one moment, for status_t.
struct EgoMotionState {
  EgoMotionCounts counts;
  bool stale = false;   // quiet for more than stale_s now
  double age_s = -1.0;  // host seconds since the last accepted message; -1: none yet
};

struct SensorStatus {
  std::string sensor, frame_id;
  Health health;             // state and reason
  bool progressing = false;  // what the systemd watchdog follows
  std::string model;         // "" until decided
  std::string return_mode;   // "" until the first data packet
  float rpm = 0;
  int time_source = 0;  // velodyne::TimeSource
  int pps = 0;          // velodyne::PpsStatus
  uint64_t position_packets = 0, gprmc_valid = 0;
  // Packets, each counted once (status_t says what each means).
  uint64_t packets_received = 0, packets_data = 0, packets_decoded = 0;
  uint64_t packets_kernel_dropped = 0, packets_missing = 0, packets_duplicate = 0;
  uint64_t packets_reordered = 0, packets_malformed = 0, packets_foreign = 0;
  uint64_t packets_inconsistent = 0, packets_model_mismatch = 0, packets_ignored = 0;
  std::vector<uint32_t> senders;  // distinct data-packet senders seen lately
  // Rotations: assembled = published + dropped + in_flight; dropped = behind + seam + unsent.
  uint64_t rotations_assembled = 0, rotations_published = 0, rotations_dropped = 0;
  uint64_t rotations_behind = 0, rotations_seam = 0, rotations_unsent = 0;
  uint64_t rotations_in_flight = 0, detections = 0, publish_failures = 0;
  uint64_t buffer_occupancy = 0, buffer_depth = 0;
  // The tracker's candidates placed in the ego-motion's odometry frame, and not placed (no pose
  // for their time); the deskew's clusters by the odometry, by the tracker's model, without.
  uint64_t ego_placed = 0, ego_missing = 0;
  uint64_t deskewed_ego = 0, deskewed_model = 0, deskew_without_motion = 0;
  std::vector<std::string> stage_names;  // "queue", "detect", "order", "publish", "total", ...
  std::vector<Percentiles> stages;       // milliseconds, same order
  std::string error;                     // why the pipeline stopped early, if it did
};

}  // namespace lidartag::daemon
