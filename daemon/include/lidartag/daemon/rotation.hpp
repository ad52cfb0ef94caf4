// One rotation's trip through the daemon: a slot of the scan buffer. The receiving thread
// assembles the scan in place, a detection worker fills the result (and the decimated cloud)
// from it, the in-order stage publishes the result; then the slot is free for another rotation.
// Nothing is copied on the way and nothing is allocated once the slot has grown to the sensor.
#pragma once

#include <cstdint>

#include "lidartag/daemon/decimated_cloud.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::daemon {

// What the in-order stage publishes of one detected rotation.
struct RotationResult {
  uint64_t sequence = 0;
  int64_t stamp_ns = 0;      // first firing, ns since the epoch
  int64_t end_stamp_ns = 0;  // last column's firing
  bool complete = false;
  int columns = 0;
  int points = 0;
  float rpm = 0;
  // Steady-clock times (ns): rotation assembled, taken by the pipeline, detection finished.
  int64_t assembled_ns = 0, taken_ns = 0, detected_ns = 0;
  detector::ScanResult detection;
  // Every k-th column's returns, when lcm.cloud_decimation = k > 0 (taken by the worker, so the
  // in-order stage only publishes).
  DecimatedCloud cloud;
};

struct Rotation {
  Scan scan;                 // sized by the batcher when first filled
  int64_t assembled_ns = 0;  // steady clock: when the receiver finished the rotation
  // The daemon's count of rotations assembled before this one: the published `sequence`, so that
  // its gaps are exactly the rotations dropped (the batcher's own counter starts again when the
  // capture reader replaces it, e.g. on a model change).
  uint64_t sequence = 0;
  uint64_t order = 0;  // place in the pipeline's publication order (0, 1, 2, ...)
  RotationResult result;
};

}  // namespace lidartag::daemon
