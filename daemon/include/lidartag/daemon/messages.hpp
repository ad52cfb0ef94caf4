// Conversions from the pipeline's results to the LCM types of lcmtypes/ (package lidartag). Fill
// a message object that the caller reuses, so that steady state does not allocate.
#pragma once

#include <cstdint>
#include <string>

#include "lidartag/daemon/rotation.hpp"
#include "lidartag/daemon/sensor_status.hpp"
#include "lidartag/detector/detector.hpp"
#include "lidartag/detector/tracker.hpp"
#include "lidartag/driver/packet_source.hpp"
#include "lidartag/point_cloud_t.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "lidartag/status_t.hpp"
#include "lidartag/tag_detection_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "lidartag/tag_points_t.hpp"

namespace lidartag::daemon {

// A detection without tracking: the track fields say "not tracked" (track_id -1, decoded).
void fill_detection(const detector::Detection& d, lidartag::tag_detection_t& out);
// A detection as the tracker reports it, with its track's fields.
void fill_detection(const detector::TrackedDetection& t, lidartag::tag_detection_t& out);

// Every field of tag_detections_t: `publish_utime` host time (µs since the epoch), `latency_ms`
// assembled -> published, `dropped` rotations dropped so far.
void fill_detections(const RotationResult& r, const std::string& sensor,
                     const std::string& frame_id, int64_t publish_utime, double latency_ms,
                     int64_t dropped, lidartag::tag_detections_t& out);

// With the tracker on: after fill_detections, the detections and track counts of the tracker's
// result for the same rotation (Tracker::update on r.detection, rotations in order).
void fill_tracked_detections(const detector::TrackerResult& tracked,
                             lidartag::tag_detections_t& out);

// The detections' points (detector::ScanResult::tag_points), detection after detection.
void fill_tag_points(const RotationResult& r, const std::string& sensor,
                     const std::string& frame_id, lidartag::tag_points_t& out);

// The rotation's decimated cloud (RotationResult::cloud).
void fill_point_cloud(const RotationResult& r, const std::string& sensor,
                      const std::string& frame_id, lidartag::point_cloud_t& out);

void fill_status(const SensorStatus& s, int64_t utime, double uptime_s, lidartag::status_t& out);
// The ego-motion input's fields of status_t (version 2); null: no input (ego_enabled false, every
// count 0). fill_status leaves them as null gives.
void fill_ego_status(const EgoMotionState* ego, lidartag::status_t& out);

void fill_raw_packet(const driver::RawPacket& p, const std::string& sensor,
                     lidartag::raw_packet_t& out);

// Host time, microseconds since the epoch.
int64_t wall_utime();

}  // namespace lidartag::daemon
