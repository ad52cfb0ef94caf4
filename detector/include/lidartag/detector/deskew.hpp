// Deskewing a cluster (issue 33, item 1): a spinning LiDAR fires a tag's points over a few
// milliseconds (a 1.2 m tag at 7 m spans 10 deg of azimuth: 2.8 ms at 600 rpm), and a sensor that
// moves meanwhile sees each point from another pose. Before the plane, corner and pose fits, each
// point of a cluster can be moved to where the sensor would have seen it at the cluster's centre
// time (the firing time of the point nearest the cluster's centroid), with the sensor's motion:
// the robot's odometry (EgoMotion: the interpolated poses at each point's time and at the centre
// time) when it covers the cluster, else the tracker's constant-velocity model of the static world
// (Tracker::motion()) when it knows one. Pure; no allocation; never throws.
#pragma once

#include <cstdint>
#include <span>

#include "lidartag/detector/track_motion.hpp"
#include "lidartag/detector/types.hpp"
#include "lidartag/driver/scan.hpp"

namespace lidartag::detector {

class EgoMotion;

// The deskew's setting (DetectorOptions::deskew; the daemon's `detector.deskew:` section).
struct DeskewOptions {
  // Move each cluster's points to its centre time with the sensor's motion (SensorMotion) before
  // the fits. Default false: the points as fired. Costs two pose look-ups per point of the
  // clusters that pass validation (a few microseconds a cluster); without a motion it does
  // nothing (ScanResult::deskew_without_motion counts such clusters).
  bool enabled = false;
};

// What is known of the sensor's motion during one scan, for the deskew.
struct SensorMotion {
  // The sensor's poses in an odometry frame, on the clock of Scan::stamp_ns (tried first); read
  // only during Detector::detect.
  const EgoMotion* ego = nullptr;
  // The apparent motion of the static world in the sensor's frame (Tracker::motion(); the
  // sensor's own motion reversed), used where `ego` has no pose for the cluster's times.
  Motion model;
};

struct Deskewed {
  DeskewSource source = DeskewSource::kNone;
  double center_s = 0.0;  // the time the points were moved to, seconds from the scan's stamp
};

// Moves `points` (a cluster of `scan`, each point's time read from scan.time_s at its ring and
// column) to the cluster's centre time. Returns the source used (kNone: unchanged) and that time.
Deskewed deskew_cluster(std::span<ClusterPoint> points, const Scan& scan,
                        const SensorMotion& motion) noexcept;

}  // namespace lidartag::detector
