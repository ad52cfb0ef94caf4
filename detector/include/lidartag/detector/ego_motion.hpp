// The sensor's own motion, when the robot knows it (issue 33, item 1): stamped poses of the
// sensor in an odometry frame (or stamped twists, integrated into such poses), kept in a fixed
// ring and interpolated to any time between them, so that the tracker can place each candidate in
// the odometry frame at its own time (Candidate::time_center_s) and average a static tag there.
// Pure: samples in, poses out; no I/O (the daemon feeds it from LCM), no allocation after
// construction, never throws after construction. docs/tracking.md, "Ego-motion".
//
// Conventions. A pose is the sensor frame -> odometry frame: a point X in the sensor's frame at
// that time is at orientation * X + position in the odometry frame (metres). A twist is the
// sensor's own velocity, in the sensor's frame at that time: linear m/s, angular rad/s (right
// hand, about the sensor's axes). Stamps are nanoseconds on the clock of the scans' stamps
// (Scan::stamp_ns; a candidate's time is stamp_ns + time_center_s).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "lidartag/detector/options.hpp"

namespace lidartag::detector {

// Every setting of EgoMotion, with its default, unit and effect.
struct EgoMotionOptions {
  // Samples kept, newest first out (memory allocated at construction). Default 512 (5 s of a
  // 100 Hz odometry; the tracker looks back one window, 1 s at 600 rpm).
  int capacity = 512;
  // Two samples further apart than this are not interpolated between: a time in that gap has no
  // pose (the tracker falls back to its own motion model), seconds. Default 0.2 (a 10 Hz
  // odometry with one message lost still interpolates). Twists further apart than this start a
  // new segment (the integration across the gap is unknown): poses of two segments are in two
  // different odometry frames and never compared.
  double max_gap_s = 0.2;
  // A time past the newest sample (the odometry lags the scan) by at most this is extrapolated
  // with the last two samples' velocity, seconds. Default 0.05. Later: no pose (stale).
  double max_extrapolation_s = 0.05;
};

// The rule table of EgoMotionOptions (the daemon's `ego_motion:` section), as visit_options.
template <class V>
void visit_ego_motion_options(V& v, EgoMotionOptions& o) {
  using namespace rules;
  v.field("capacity", o.capacity, closed(2, 1000000), "samples");
  v.field("max_gap_s", o.max_gap_s, open_closed(0.0, 60.0), "s");
  v.field("max_extrapolation_s", o.max_extrapolation_s, closed(0.0, 10.0), "s");
}

// Every rule of EgoMotionOptions. Throws OptionsError naming the first bad option
// ("ego_motion.capacity").
void validate_ego_motion_options(const EgoMotionOptions& options);

// A pose of the sensor in the odometry frame.
struct EgoPose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  // Odometry frames: poses of different segments are not comparable (twists across a gap).
  uint32_t segment = 0;
};

// What happened to a sample offered to EgoMotion.
enum class EgoSample : unsigned char {
  kAccepted,
  kOutOfOrder,  // stamp not after the newest sample's: dropped
  kInvalid,     // not finite, or an orientation that is no rotation (norm off 1 by > 1 %)
};

// What a lookup found.
enum class EgoLookup : unsigned char {
  kOk,
  kEmpty,   // no sample yet
  kBefore,  // older than the oldest sample kept
  kGap,     // between two samples more than max_gap_s apart, or of two segments
  kStale,   // past the newest sample by more than max_extrapolation_s
};

const char* to_string(EgoSample s);
const char* to_string(EgoLookup l);

// Counters of the samples offered, for a health report.
struct EgoMotionCounters {
  uint64_t accepted = 0, out_of_order = 0, invalid = 0;
  uint64_t segments = 0;  // twist segments started (the first included)
};

class EgoMotion {
 public:
  // Throws OptionsError on a bad option.
  explicit EgoMotion(EgoMotionOptions options = {});

  const EgoMotionOptions& options() const { return opt_; }

  // A pose of the sensor at stamp_ns. Never throws.
  EgoSample add_pose(int64_t stamp_ns, const Eigen::Vector3d& position,
                     const Eigen::Quaterniond& orientation) noexcept;
  // A twist of the sensor at stamp_ns, integrated from the previous sample (the previous twist
  // held over the interval: the sensor's pose is known at the twists' stamps); the first one, or
  // one after a gap, starts a new segment at the identity. Do not mix with add_pose. Never throws.
  EgoSample add_twist(int64_t stamp_ns, const Eigen::Vector3d& linear_mps,
                      const Eigen::Vector3d& angular_rad_s) noexcept;

  // The sensor's pose at t_ns: interpolated (position linearly, orientation by slerp) between the
  // samples around it, or extrapolated a little past the newest. Never throws.
  EgoLookup at(int64_t t_ns, EgoPose& out) const noexcept;

  // The newest sample's stamp (0 when empty), and whether there is one.
  int64_t newest_ns() const noexcept;
  bool empty() const noexcept { return count_ == 0; }
  const EgoMotionCounters& counters() const noexcept { return counters_; }
  // Forgets every sample (counters kept).
  void clear() noexcept;

 private:
  struct Sample {
    int64_t t_ns = 0;
    EgoPose pose;
    Eigen::Vector3d linear = Eigen::Vector3d::Zero(), angular = Eigen::Vector3d::Zero();
  };
  const Sample& sample(size_t i) const;  // i-th oldest
  void push(const Sample& s);

  EgoMotionOptions opt_;
  std::vector<Sample> ring_;
  size_t head_ = 0;  // next slot written
  size_t count_ = 0;
  uint32_t segment_ = 0;
  EgoMotionCounters counters_;
};

}  // namespace lidartag::detector
