// A sensor pipeline's health and counters at one moment: what status_t and systemd's STATUS=
// report. Plain data, no LCM.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lidartag/daemon/health.hpp"
#include "lidartag/daemon/latency_window.hpp"

namespace lidartag::daemon {

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
  std::vector<std::string> stage_names;  // "queue", "detect", "order", "publish", "total", ...
  std::vector<Percentiles> stages;       // milliseconds, same order
  std::string error;                     // why the pipeline stopped early, if it did
};

}  // namespace lidartag::daemon
