#include "lidartag/daemon/messages.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace lidartag::daemon {

int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void fill_detection(const detector::Detection& d, lidartag::tag_detection_t& out) {
  out.family.assign(d.family.data(), d.family.size());
  out.family_index = d.family_index;
  out.id = d.id;
  out.size_m = d.size_m;
  for (int i = 0; i < 3; ++i) out.position[i] = d.position[i];
  out.orientation[0] = d.orientation.w();
  out.orientation[1] = d.orientation.x();
  out.orientation[2] = d.orientation.y();
  out.orientation[3] = d.orientation.z();
  for (size_t c = 0; c < 4; ++c) {
    for (int i = 0; i < 3; ++i) out.corners[c][i] = d.corners[c][i];
  }
  out.score = d.score;
  out.margin = d.margin;
  out.points = d.points;
  out.fit_cost = d.fit_cost;
  out.time_first_s = d.time_first_s;
  out.time_center_s = d.time_center_s;
  out.measured_size_m = d.measured_size_m;
  out.size_warning = d.size_warning;
  out.time_last_s = d.time_last_s;
  out.decoded = true;
  out.track_id = -1;
  out.track_rotations = 0;
  out.confirmed = false;
  out.track_margin = 0.0;
  out.track_window = 0;
  for (int i = 0; i < 3; ++i) out.track_position[i] = out.track_position_std[i] = 0.0;
  for (int i = 0; i < 4; ++i) out.track_orientation[i] = i == 0 ? 1.0 : 0.0;
  out.track_angle_std_deg = 0.0;
  out.track_moving = false;
  for (int i = 0; i < 3; ++i) out.track_velocity[i] = out.track_turn_deg_s[i] = 0.0;
}

void fill_detection(const detector::TrackedDetection& t, lidartag::tag_detection_t& out) {
  fill_detection(t.detection, out);
  const detector::TrackInfo& k = t.track;
  out.decoded = t.decoded;
  out.track_id = k.track_id;
  if (k.track_id < 0) return;
  out.track_rotations = k.rotations;
  out.confirmed = k.confirmed;
  out.track_margin = k.margin_cells;
  out.track_window = k.window_rotations;
  for (int i = 0; i < 3; ++i) {
    out.track_position[i] = k.position[i];
    out.track_position_std[i] = k.position_std_m[i];
  }
  out.track_orientation[0] = k.orientation.w();
  out.track_orientation[1] = k.orientation.x();
  out.track_orientation[2] = k.orientation.y();
  out.track_orientation[3] = k.orientation.z();
  out.track_angle_std_deg = k.angle_std_deg;
  out.track_moving = k.moving;
  for (int i = 0; i < 3; ++i) {
    out.track_velocity[i] = k.velocity_mps[i];
    out.track_turn_deg_s[i] = k.turn_deg_s[i];
  }
}

void fill_detections(const RotationResult& r, const std::string& sensor,
                     const std::string& frame_id, int64_t publish_utime, double latency_ms,
                     int64_t dropped, lidartag::tag_detections_t& out) {
  out.utime = r.stamp_ns / 1000;
  out.frame_id = frame_id;
  out.sensor = sensor;
  out.sequence = static_cast<int64_t>(r.sequence);
  out.end_utime = r.end_stamp_ns / 1000;
  out.publish_utime = publish_utime;
  out.latency_ms = latency_ms;
  out.detection_ms = r.detection.total_ms();
  out.dropped_rotations = dropped;
  out.complete = r.complete;
  out.columns = r.columns;
  out.points = r.points;
  out.rpm = r.rpm;
  out.features = r.detection.features;
  out.clusters = r.detection.clusters;
  out.tracks = 0;
  out.confirmed_tracks = 0;
  const auto& detections = r.detection.detections;
  out.ndetections = static_cast<int32_t>(detections.size());
  out.detections.resize(detections.size());
  for (size_t i = 0; i < detections.size(); ++i) fill_detection(detections[i], out.detections[i]);
}

void fill_tracked_detections(const detector::TrackerResult& tracked,
                             lidartag::tag_detections_t& out) {
  out.tracks = tracked.tracks;
  out.confirmed_tracks = tracked.confirmed_tracks;
  out.ndetections = static_cast<int32_t>(tracked.tags.size());
  out.detections.resize(tracked.tags.size());
  for (size_t i = 0; i < tracked.tags.size(); ++i)
    fill_detection(tracked.tags[i], out.detections[i]);
}

void fill_tag_points(const RotationResult& r, const std::string& sensor,
                     const std::string& frame_id, lidartag::tag_points_t& out) {
  out.utime = r.stamp_ns / 1000;
  out.frame_id = frame_id;
  out.sensor = sensor;
  out.sequence = static_cast<int64_t>(r.sequence);
  const auto& detections = r.detection.detections;
  const size_t n = detections.size();
  out.ntags = static_cast<int32_t>(n);
  out.family.resize(n);
  out.id.resize(n);
  out.first_point.resize(n);
  out.tag_npoints.resize(n);
  // Packed again from the detections' own spans: the message is consistent whatever
  // ScanResult::tag_points holds beyond them.
  size_t total = 0;
  for (const auto& d : detections) total += r.detection.points_of(d).size();
  out.npoints = static_cast<int32_t>(total);
  out.x.resize(total);
  out.y.resize(total);
  out.z.resize(total);
  out.intensity.resize(total);
  out.ring.resize(total);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    const auto& d = detections[i];
    const auto points = r.detection.points_of(d);
    out.family[i].assign(d.family.data(), d.family.size());
    out.id[i] = d.id;
    out.first_point[i] = static_cast<int32_t>(k);
    out.tag_npoints[i] = static_cast<int32_t>(points.size());
    for (const auto& p : points) {
      out.x[k] = p.x;
      out.y[k] = p.y;
      out.z[k] = p.z;
      out.intensity[k] = static_cast<uint8_t>(std::clamp(std::lround(p.intensity), 0L, 255L));
      out.ring[k] = static_cast<uint8_t>(p.ring);
      ++k;
    }
  }
}

void fill_point_cloud(const RotationResult& r, const std::string& sensor,
                      const std::string& frame_id, lidartag::point_cloud_t& out) {
  const DecimatedCloud& c = r.cloud;
  out.utime = r.stamp_ns / 1000;
  out.frame_id = frame_id;
  out.sensor = sensor;
  out.sequence = static_cast<int64_t>(r.sequence);
  out.decimation = c.decimation;
  out.columns = c.columns;
  out.npoints = static_cast<int32_t>(c.size());
  out.x.assign(c.x.begin(), c.x.end());
  out.y.assign(c.y.begin(), c.y.end());
  out.z.assign(c.z.begin(), c.z.end());
  out.intensity.assign(c.intensity.begin(), c.intensity.end());
  out.ring.assign(c.ring.begin(), c.ring.end());
}

void fill_ego_status(const EgoMotionState* ego, lidartag::status_t& out) {
  const EgoMotionState none;
  const EgoMotionState& e = ego != nullptr ? *ego : none;
  auto i64 = [](uint64_t v) { return static_cast<int64_t>(v); };
  out.ego_enabled = ego != nullptr;
  out.ego_received = i64(e.counts.received);
  out.ego_accepted = i64(e.counts.accepted);
  out.ego_dropped = i64(e.counts.dropped());
  out.ego_out_of_order = i64(e.counts.out_of_order);
  out.ego_invalid = i64(e.counts.invalid);
  out.ego_unknown_kind = i64(e.counts.unknown_kind);
  out.ego_undecodable = i64(e.counts.undecodable);
  out.ego_gaps = i64(e.counts.gaps);
  out.ego_stale = e.stale;
  out.ego_stale_episodes = i64(e.counts.stale_episodes);
  out.ego_age_s = e.age_s;
}

void fill_status(const SensorStatus& s, int64_t utime, double uptime_s, lidartag::status_t& out) {
  auto i64 = [](uint64_t v) { return static_cast<int64_t>(v); };
  out.utime = utime;
  out.frame_id = s.frame_id;
  out.sensor = s.sensor;
  out.uptime_s = uptime_s;
  out.healthy = s.health.healthy();
  out.state = static_cast<int8_t>(s.health.state);
  out.reason = s.health.reason;
  out.progressing = s.progressing;
  out.model = s.model;
  out.return_mode = s.return_mode;
  out.rpm = s.rpm;
  out.time_source = static_cast<int8_t>(s.time_source);
  out.pps = static_cast<int8_t>(s.pps);
  out.position_packets = i64(s.position_packets);
  out.gprmc_valid = i64(s.gprmc_valid);
  out.packets_received = i64(s.packets_received);
  out.packets_data = i64(s.packets_data);
  out.packets_decoded = i64(s.packets_decoded);
  out.packets_kernel_dropped = i64(s.packets_kernel_dropped);
  out.packets_missing = i64(s.packets_missing);
  out.packets_duplicate = i64(s.packets_duplicate);
  out.packets_reordered = i64(s.packets_reordered);
  out.packets_malformed = i64(s.packets_malformed);
  out.packets_foreign = i64(s.packets_foreign);
  out.packets_inconsistent = i64(s.packets_inconsistent);
  out.packets_model_mismatch = i64(s.packets_model_mismatch);
  out.packets_ignored = i64(s.packets_ignored);
  out.nsenders = static_cast<int32_t>(s.senders.size());
  out.senders.resize(s.senders.size());
  for (size_t i = 0; i < s.senders.size(); ++i) {
    out.senders[i] = static_cast<int32_t>(s.senders[i]);
  }
  out.rotations_assembled = i64(s.rotations_assembled);
  out.rotations_published = i64(s.rotations_published);
  out.rotations_dropped = i64(s.rotations_dropped);
  out.rotations_behind = i64(s.rotations_behind);
  out.rotations_seam = i64(s.rotations_seam);
  out.rotations_unsent = i64(s.rotations_unsent);
  out.rotations_in_flight = i64(s.rotations_in_flight);
  out.detections = i64(s.detections);
  out.publish_failures = i64(s.publish_failures);
  out.ego_placed = i64(s.ego_placed);
  out.ego_missing = i64(s.ego_missing);
  out.deskewed_ego = i64(s.deskewed_ego);
  out.deskewed_model = i64(s.deskewed_model);
  out.deskew_without_motion = i64(s.deskew_without_motion);
  fill_ego_status(nullptr, out);
  out.buffer_occupancy = static_cast<int32_t>(s.buffer_occupancy);
  out.buffer_depth = static_cast<int32_t>(s.buffer_depth);
  const size_t n = std::min(s.stage_names.size(), s.stages.size());
  out.nstages = static_cast<int32_t>(n);
  out.stage_names.assign(s.stage_names.begin(),
                         s.stage_names.begin() + static_cast<std::ptrdiff_t>(n));
  out.p50_ms.resize(n);
  out.p90_ms.resize(n);
  out.p99_ms.resize(n);
  out.max_ms.resize(n);
  for (size_t i = 0; i < n; ++i) {
    out.p50_ms[i] = s.stages[i].p50;
    out.p90_ms[i] = s.stages[i].p90;
    out.p99_ms[i] = s.stages[i].p99;
    out.max_ms[i] = s.stages[i].max;
  }
}

void fill_raw_packet(const driver::RawPacket& p, const std::string& sensor,
                     lidartag::raw_packet_t& out) {
  out.utime = p.receive_time_ns / 1000;
  out.receive_time_ns = p.receive_time_ns;
  out.sensor = sensor;
  out.source_ipv4 = static_cast<int32_t>(p.source_ipv4);
  out.port = p.destination_port;
  out.nbytes = static_cast<int32_t>(p.payload.size());
  out.data.assign(p.payload.begin(), p.payload.end());
}

}  // namespace lidartag::daemon
