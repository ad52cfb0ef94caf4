// The LCM messages: every field filled from the pipeline's results, published on an in-process
// bus (memq://) and decoded back with the generated types.
#include "lidartag/daemon/messages.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "lcm_bytes.hpp"
#include "lidartag/daemon/lcm_bus.hpp"

namespace lidartag::daemon {
namespace {

// Receives every message of one channel on the bus as raw bytes.
struct Capture {
  std::vector<std::vector<uint8_t>> messages;
  void handle(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const auto* p = static_cast<const uint8_t*>(rbuf->data);
    messages.emplace_back(p, p + rbuf->data_size);
  }
};

using lcm_test::decode;

RotationResult sample_result() {
  RotationResult r;
  r.sequence = 17;
  r.stamp_ns = 1700000000123456789;
  r.end_stamp_ns = r.stamp_ns + 99'000'000;
  r.complete = true;
  r.columns = 1808;
  r.points = 50000;
  r.rpm = 600.5f;
  r.detection.features = 300;
  r.detection.clusters = 12;
  r.detection.timing_ms[0] = 1.5;
  detector::Detection d;
  d.family_index = 1;
  d.family = "tag25h9";
  d.id = 7;
  d.size_m = 0.8;
  d.position = {4.0, 0.9, 0.1};
  d.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  for (size_t c = 0; c < 4; ++c)
    d.corners[c] = Eigen::Vector3d(4.0, 0.1 * double(c), -0.2 * double(c));
  d.score = 0.93;
  d.margin = 3.5;
  d.points = 812;
  d.fit_cost = 1.25;
  r.detection.detections.push_back(d);
  return r;
}

TEST(Messages, DetectionsCarryEveryFieldThroughMemq) {
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("FRONT_LIDARTAG_DETECTIONS", &Capture::handle, &capture);
  const RotationResult r = sample_result();
  lidartag::tag_detections_t msg;
  fill_detections(r, "front", "velodyne_front", 1700000000200000, 12.5, 3, msg);
  ASSERT_TRUE(bus.publish("FRONT_LIDARTAG_DETECTIONS", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  ASSERT_EQ(capture.messages.size(), 1u);
  const auto got = decode<lidartag::tag_detections_t>(capture.messages[0]);
  EXPECT_EQ(got.utime, 1700000000123456);
  EXPECT_EQ(got.end_utime, 1700000000222456);
  EXPECT_EQ(got.publish_utime, 1700000000200000);
  EXPECT_EQ(got.sensor, "front");
  EXPECT_EQ(got.frame_id, "velodyne_front");
  EXPECT_EQ(got.sequence, 17);
  EXPECT_EQ(got.latency_ms, 12.5);
  EXPECT_EQ(got.detection_ms, 1.5);
  EXPECT_EQ(got.dropped_rotations, 3);
  EXPECT_TRUE(got.complete);
  EXPECT_EQ(got.columns, 1808);
  EXPECT_EQ(got.points, 50000);
  EXPECT_FLOAT_EQ(got.rpm, 600.5f);
  EXPECT_EQ(got.features, 300);
  EXPECT_EQ(got.clusters, 12);
  ASSERT_EQ(got.ndetections, 1);
  const auto& t = got.detections[0];
  const auto& d = r.detection.detections[0];
  EXPECT_EQ(t.family, "tag25h9");
  EXPECT_EQ(t.family_index, 1);
  EXPECT_EQ(t.id, 7);
  EXPECT_EQ(t.size_m, 0.8);
  EXPECT_EQ(t.position[0], 4.0);
  EXPECT_EQ(t.position[2], 0.1);
  EXPECT_EQ(t.orientation[0], d.orientation.w());
  EXPECT_EQ(t.orientation[3], d.orientation.z());
  EXPECT_EQ(t.corners[3][1], d.corners[3].y());
  EXPECT_EQ(t.corners[2][2], d.corners[2].z());
  EXPECT_EQ(t.score, 0.93);
  EXPECT_EQ(t.margin, 3.5);
  EXPECT_EQ(t.points, 812);
  EXPECT_EQ(t.fit_cost, 1.25);
  // Without the tracker: decoded alone, not tracked.
  EXPECT_TRUE(t.decoded);
  EXPECT_EQ(t.track_id, -1);
  EXPECT_FALSE(t.confirmed);
  EXPECT_EQ(t.track_rotations, 0);
  EXPECT_EQ(got.tracks, 0);
  EXPECT_EQ(got.confirmed_tracks, 0);
}

// The tracker's report of the rotation replaces the detections: each with its track's fields, a
// tag confirmed by its track only (decoded false) after them; the track counts.
TEST(Messages, TrackedDetectionsCarryTheTrackFieldsThroughMemq) {
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("LIDARTAG_DETECTIONS", &Capture::handle, &capture);
  const RotationResult r = sample_result();
  detector::TrackerResult tracked;
  tracked.tracks = 3;
  tracked.confirmed_tracks = 2;
  detector::TrackedDetection a;
  a.detection = r.detection.detections[0];
  a.track.track_id = 12;
  a.track.rotations = 40;
  a.track.confirmed = true;
  a.track.margin_cells = 2.5;
  a.track.window_rotations = 10;
  a.track.position = {4.01, 0.91, 0.11};
  a.track.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitZ()));
  a.track.position_std_m = {0.001, 0.002, 0.003};
  a.track.angle_std_deg = 0.4;
  a.track.moving = true;
  a.track.velocity_mps = {-1.0, 0.25, 0.0};
  a.track.turn_deg_s = {0.0, 0.0, -30.0};
  detector::TrackedDetection b = a;
  b.decoded = false;
  b.detection.id = 9;
  b.track.track_id = 13;
  b.track.rotations = 4;
  detector::TrackedDetection c = a;
  c.track = detector::TrackInfo{};  // more tags than tracks: untracked
  tracked.tags = {a, b, c};
  lidartag::tag_detections_t msg;
  fill_detections(r, "", "velodyne", 0, 0, 0, msg);
  fill_tracked_detections(tracked, msg);
  ASSERT_TRUE(bus.publish("LIDARTAG_DETECTIONS", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  const auto got = decode<lidartag::tag_detections_t>(capture.messages.at(0));
  EXPECT_EQ(got.tracks, 3);
  EXPECT_EQ(got.confirmed_tracks, 2);
  ASSERT_EQ(got.ndetections, 3);
  const auto& t = got.detections[0];
  EXPECT_EQ(t.id, 7);
  EXPECT_EQ(t.points, 812);
  EXPECT_TRUE(t.decoded);
  EXPECT_EQ(t.track_id, 12);
  EXPECT_EQ(t.track_rotations, 40);
  EXPECT_TRUE(t.confirmed);
  EXPECT_EQ(t.track_margin, 2.5);
  EXPECT_EQ(t.track_window, 10);
  EXPECT_EQ(t.track_position[1], 0.91);
  EXPECT_EQ(t.track_orientation[0], a.track.orientation.w());
  EXPECT_EQ(t.track_orientation[3], a.track.orientation.z());
  EXPECT_EQ(t.track_position_std[2], 0.003);
  EXPECT_EQ(t.track_angle_std_deg, 0.4);
  EXPECT_TRUE(t.track_moving);
  EXPECT_EQ(t.track_velocity[0], -1.0);
  EXPECT_EQ(t.track_velocity[1], 0.25);
  EXPECT_EQ(t.track_turn_deg_s[2], -30.0);
  EXPECT_FALSE(got.detections[1].decoded);
  EXPECT_EQ(got.detections[1].id, 9);
  EXPECT_EQ(got.detections[1].track_id, 13);
  EXPECT_EQ(got.detections[2].track_id, -1);
  EXPECT_FALSE(got.detections[2].confirmed);
  EXPECT_EQ(got.detections[2].track_rotations, 0);
  EXPECT_FALSE(got.detections[2].track_moving);
  EXPECT_EQ(got.detections[2].track_turn_deg_s[2], 0.0);
}

TEST(Messages, EmptyRotationIsStillAMessage) {
  RotationResult r = sample_result();
  r.detection.detections.clear();
  lidartag::tag_detections_t msg;
  fill_detections(sample_result(), "a", "f", 0, 0, 0, msg);  // reused: shrinks to the new count
  fill_detections(r, "a", "f", 0, 0, 0, msg);
  EXPECT_EQ(msg.ndetections, 0);
  EXPECT_TRUE(msg.detections.empty());
  std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
}

// sample_result() with a second detection and both detections' points.
RotationResult result_with_points() {
  RotationResult r = sample_result();
  detector::Detection second = r.detection.detections[0];
  second.family_index = 0;
  second.family = "tag16h5";
  second.id = 3;
  r.detection.detections.push_back(second);
  auto& points = r.detection.tag_points;
  int first = 0;
  for (auto& d : r.detection.detections) {
    d.first_point = first;
    d.points = d.id == 7 ? 5 : 3;
    for (int i = 0; i < d.points; ++i) {
      detector::ClusterPoint p;
      p.x = 4.0f + 0.01f * static_cast<float>(first + i);
      p.y = -0.5f * static_cast<float>(i);
      p.z = 0.25f * static_cast<float>(d.id);
      p.intensity = static_cast<float>(20 + 50 * i);
      p.ring = 10 + i;
      points.push_back(p);
    }
    first += d.points;
  }
  return r;
}

TEST(Messages, TagPointsCarryEachDetectionsPointsThroughMemq) {
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("FRONT_LIDARTAG_TAG_POINTS", &Capture::handle, &capture);
  const RotationResult r = result_with_points();
  lidartag::tag_points_t msg;
  fill_tag_points(r, "front", "velodyne_front", msg);
  ASSERT_TRUE(bus.publish("FRONT_LIDARTAG_TAG_POINTS", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  ASSERT_EQ(capture.messages.size(), 1u);
  const auto got = decode<lidartag::tag_points_t>(capture.messages[0]);
  EXPECT_EQ(got.utime, 1700000000123456);
  EXPECT_EQ(got.sensor, "front");
  EXPECT_EQ(got.frame_id, "velodyne_front");
  EXPECT_EQ(got.sequence, 17);
  ASSERT_EQ(got.ntags, 2);
  EXPECT_EQ(got.family, (std::vector<std::string>{"tag25h9", "tag16h5"}));
  EXPECT_EQ(got.id, (std::vector<int32_t>{7, 3}));
  EXPECT_EQ(got.first_point, (std::vector<int32_t>{0, 5}));
  EXPECT_EQ(got.tag_npoints, (std::vector<int32_t>{5, 3}));
  ASSERT_EQ(got.npoints, 8);
  const auto& points = r.detection.tag_points;
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(got.x[i], points[i].x);
    EXPECT_EQ(got.y[i], points[i].y);
    EXPECT_EQ(got.z[i], points[i].z);
    EXPECT_EQ(got.intensity[i], static_cast<uint8_t>(points[i].intensity));
    EXPECT_EQ(got.ring[i], points[i].ring);
  }
  EXPECT_EQ(got.intensity[4], 220);  // unsigned, above 127
  // Reused for a rotation with fewer detections: counts and arrays shrink together.
  RotationResult one = r;
  one.detection.detections.pop_back();
  fill_tag_points(one, "front", "velodyne_front", msg);
  EXPECT_EQ(msg.ntags, 1);
  EXPECT_EQ(msg.family.size(), 1u);
  EXPECT_EQ(msg.npoints, 5);
  EXPECT_EQ(msg.x.size(), 5u);
  EXPECT_EQ(msg.ring.size(), 5u);
  std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
}

TEST(Messages, PointCloudCarriesTheDecimatedRotationThroughMemq) {
  RotationResult r = sample_result();
  Scan scan;
  scan.reserve(3, 1, 10);
  scan.columns = 10;
  for (int ring = 0; ring < 3; ++ring)
    for (int c = 0; c < 10; ++c) {
      const size_t i = scan.at(0, ring, c);
      scan.x[i] = static_cast<float>(c);
      scan.y[i] = static_cast<float>(ring);
      scan.z[i] = -1.0f;
      scan.range[i] = ring == 1 && c == 4 ? 0.0f : 5.0f;  // one cell without a return
      scan.intensity[i] = static_cast<uint8_t>(200 + ring);
    }
  decimate_scan(scan, 4, r.cloud);  // columns 0, 4, 8
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("LIDARTAG_CLOUD", &Capture::handle, &capture);
  lidartag::point_cloud_t msg;
  fill_point_cloud(r, "front", "velodyne_front", msg);
  ASSERT_TRUE(bus.publish("LIDARTAG_CLOUD", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  const auto got = decode<lidartag::point_cloud_t>(capture.messages.at(0));
  EXPECT_EQ(got.utime, 1700000000123456);
  EXPECT_EQ(got.sensor, "front");
  EXPECT_EQ(got.frame_id, "velodyne_front");
  EXPECT_EQ(got.sequence, 17);
  EXPECT_EQ(got.decimation, 4);
  EXPECT_EQ(got.columns, 3);
  ASSERT_EQ(got.npoints, 8);
  EXPECT_EQ(got.x, (std::vector<float>{0, 0, 0, 4, 4, 8, 8, 8}));
  EXPECT_EQ(got.y, (std::vector<float>{0, 1, 2, 0, 2, 0, 1, 2}));
  EXPECT_EQ(got.z, std::vector<float>(8, -1.0f));
  EXPECT_EQ(got.intensity, (std::vector<uint8_t>{200, 201, 202, 200, 202, 200, 201, 202}));
  EXPECT_EQ(got.ring, (std::vector<uint8_t>{0, 1, 2, 0, 2, 0, 1, 2}));
}

TEST(Messages, StatusCarriesHealthEveryCounterAndStagePercentiles) {
  SensorStatus s;
  s.sensor = "front";
  s.frame_id = "velodyne";
  s.health = {HealthState::kPacketLoss, "3.0 % of the data packets missing"};
  s.progressing = true;
  s.model = "vlp32c";
  s.return_mode = "strongest";
  s.rpm = 599.0f;
  s.time_source = 1;
  s.pps = 2;
  s.position_packets = 31;
  s.gprmc_valid = 30;
  // Every counter a different value: each lands in its own field.
  s.packets_received = 1000;
  s.packets_data = 990;
  s.packets_decoded = 980;
  s.packets_kernel_dropped = 3;
  s.packets_missing = 4;
  s.packets_duplicate = 5;
  s.packets_reordered = 6;
  s.packets_malformed = 7;
  s.packets_foreign = 8;
  s.packets_inconsistent = 9;
  s.packets_model_mismatch = 11;
  s.packets_ignored = 12;
  s.senders = {0xC0A801C9, 0xC0A801CA};
  s.rotations_assembled = 40;
  s.rotations_published = 30;
  s.rotations_dropped = 8;
  s.rotations_behind = 5;
  s.rotations_seam = 2;
  s.rotations_unsent = 1;
  s.rotations_in_flight = 2;
  s.detections = 57;
  s.publish_failures = 13;
  s.buffer_occupancy = 1;
  s.buffer_depth = 4;
  s.stage_names = {"queue", "detect"};
  s.stages = {Percentiles{1, 2, 3, 4, 10}, Percentiles{5, 6, 7, 8, 10}};
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("LIDARTAG_STATUS", &Capture::handle, &capture);
  lidartag::status_t msg;
  fill_status(s, 123, 4.5, msg);
  ASSERT_TRUE(bus.publish("LIDARTAG_STATUS", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  const auto got = decode<lidartag::status_t>(capture.messages.at(0));
  EXPECT_EQ(got.utime, 123);
  EXPECT_EQ(got.uptime_s, 4.5);
  EXPECT_FALSE(got.healthy);
  EXPECT_EQ(got.state, int8_t{lidartag::status_t::STATE_PACKET_LOSS});
  EXPECT_EQ(got.reason, "3.0 % of the data packets missing");
  EXPECT_TRUE(got.progressing);
  EXPECT_EQ(got.model, "vlp32c");
  EXPECT_EQ(got.return_mode, "strongest");
  EXPECT_EQ(got.rpm, 599.0f);
  EXPECT_EQ(got.time_source, int8_t{lidartag::status_t::TIME_GPS});
  EXPECT_EQ(got.pps, int8_t{lidartag::status_t::PPS_LOCKED});
  EXPECT_EQ(got.position_packets, 31);
  EXPECT_EQ(got.gprmc_valid, 30);
  EXPECT_EQ(got.packets_received, 1000);
  EXPECT_EQ(got.packets_data, 990);
  EXPECT_EQ(got.packets_decoded, 980);
  EXPECT_EQ(got.packets_kernel_dropped, 3);
  EXPECT_EQ(got.packets_missing, 4);
  EXPECT_EQ(got.packets_duplicate, 5);
  EXPECT_EQ(got.packets_reordered, 6);
  EXPECT_EQ(got.packets_malformed, 7);
  EXPECT_EQ(got.packets_foreign, 8);
  EXPECT_EQ(got.packets_inconsistent, 9);
  EXPECT_EQ(got.packets_model_mismatch, 11);
  EXPECT_EQ(got.packets_ignored, 12);
  ASSERT_EQ(got.nsenders, 2);
  EXPECT_EQ(static_cast<uint32_t>(got.senders[1]), 0xC0A801CAu);
  EXPECT_EQ(got.rotations_assembled, 40);
  EXPECT_EQ(got.rotations_published, 30);
  EXPECT_EQ(got.rotations_dropped, 8);
  EXPECT_EQ(got.rotations_behind, 5);
  EXPECT_EQ(got.rotations_seam, 2);
  EXPECT_EQ(got.rotations_unsent, 1);
  EXPECT_EQ(got.rotations_in_flight, 2);
  EXPECT_EQ(got.detections, 57);
  EXPECT_EQ(got.publish_failures, 13);
  EXPECT_EQ(got.buffer_occupancy, 1);
  EXPECT_EQ(got.buffer_depth, 4);
  ASSERT_EQ(got.nstages, 2);
  EXPECT_EQ(got.stage_names[1], "detect");
  EXPECT_EQ(got.p90_ms[1], 6);
  EXPECT_EQ(got.max_ms[0], 4);
}

// status_t version 2: the ego-motion input's counters, the tracker's placements and the deskew's
// clusters, each a different value, each in its own field; without an input all 0 and disabled.
TEST(Messages, EgoMotionCountersLandEachInItsOwnField) {
  SensorStatus s;
  s.ego_placed = 41;
  s.ego_missing = 42;
  s.deskewed_ego = 43;
  s.deskewed_model = 44;
  s.deskew_without_motion = 45;
  EgoMotionState e;
  e.counts.received = 100;
  e.counts.accepted = 90;
  e.counts.out_of_order = 1;
  e.counts.invalid = 2;
  e.counts.unknown_kind = 3;
  e.counts.undecodable = 4;
  e.counts.gaps = 5;
  e.counts.stale_episodes = 6;
  e.stale = true;
  e.age_s = 0.75;
  lidartag::status_t msg;
  fill_status(s, 1, 1.0, msg);
  EXPECT_FALSE(msg.ego_enabled);
  EXPECT_EQ(msg.ego_received, 0);
  EXPECT_EQ(msg.ego_age_s, -1.0);
  fill_ego_status(&e, msg);
  LcmBus bus("memq://");
  Capture capture;
  bus.lcm().subscribe("LIDARTAG_STATUS", &Capture::handle, &capture);
  ASSERT_TRUE(bus.publish("LIDARTAG_STATUS", msg));
  ASSERT_EQ(bus.lcm().handleTimeout(100), 1);
  const auto got = decode<lidartag::status_t>(capture.messages.at(0));
  EXPECT_TRUE(got.ego_enabled);
  EXPECT_EQ(got.ego_received, 100);
  EXPECT_EQ(got.ego_accepted, 90);
  EXPECT_EQ(got.ego_dropped, 10);
  EXPECT_EQ(got.ego_out_of_order, 1);
  EXPECT_EQ(got.ego_invalid, 2);
  EXPECT_EQ(got.ego_unknown_kind, 3);
  EXPECT_EQ(got.ego_undecodable, 4);
  EXPECT_EQ(got.ego_received, got.ego_accepted + got.ego_dropped);
  EXPECT_EQ(got.ego_gaps, 5);
  EXPECT_TRUE(got.ego_stale);
  EXPECT_EQ(got.ego_stale_episodes, 6);
  EXPECT_EQ(got.ego_age_s, 0.75);
  EXPECT_EQ(got.ego_placed, 41);
  EXPECT_EQ(got.ego_missing, 42);
  EXPECT_EQ(got.deskewed_ego, 43);
  EXPECT_EQ(got.deskewed_model, 44);
  EXPECT_EQ(got.deskew_without_motion, 45);
}

TEST(Messages, StatusStatesMatchTheLcmConstants) {
  using st = lidartag::status_t;
  EXPECT_EQ(static_cast<int>(HealthState::kHealthy), int{st::STATE_HEALTHY});
  EXPECT_EQ(static_cast<int>(HealthState::kWaiting), int{st::STATE_WAITING});
  EXPECT_EQ(static_cast<int>(HealthState::kSilent), int{st::STATE_SILENT});
  EXPECT_EQ(static_cast<int>(HealthState::kModelMismatch), int{st::STATE_MODEL_MISMATCH});
  EXPECT_EQ(static_cast<int>(HealthState::kSeveralSources), int{st::STATE_SEVERAL_SOURCES});
  EXPECT_EQ(static_cast<int>(HealthState::kRateImplausible), int{st::STATE_RATE_IMPLAUSIBLE});
  EXPECT_EQ(static_cast<int>(HealthState::kPacketLoss), int{st::STATE_PACKET_LOSS});
  EXPECT_EQ(static_cast<int>(HealthState::kFallingBehind), int{st::STATE_FALLING_BEHIND});
  EXPECT_EQ(static_cast<int>(HealthState::kPublishFailing), int{st::STATE_PUBLISH_FAILING});
  EXPECT_EQ(static_cast<int>(HealthState::kStalled), int{st::STATE_STALLED});
  EXPECT_EQ(static_cast<int>(HealthState::kError), int{st::STATE_ERROR});
  EXPECT_EQ(static_cast<int>(HealthState::kEnded), int{st::STATE_ENDED});
  EXPECT_EQ(static_cast<int>(HealthState::kNotDecoding), int{st::STATE_NOT_DECODING});
}

TEST(Messages, RawPacketKeepsBytesPortAndTime) {
  const std::vector<uint8_t> payload = {1, 2, 3, 250};
  driver::RawPacket p;
  p.payload = payload;
  p.receive_time_ns = 1700000000123456789;
  p.source_ipv4 = 0xC0A801C9;
  p.destination_port = 2368;
  lidartag::raw_packet_t msg;
  fill_raw_packet(p, "front", msg);
  EXPECT_EQ(msg.utime, 1700000000123456);
  EXPECT_EQ(msg.receive_time_ns, p.receive_time_ns);
  EXPECT_EQ(static_cast<uint32_t>(msg.source_ipv4), 0xC0A801C9u);
  EXPECT_EQ(msg.port, 2368);
  EXPECT_EQ(msg.nbytes, 4);
  EXPECT_EQ(msg.data, payload);
}

TEST(Messages, BadUrlIsASetupError) {
  EXPECT_THROW(LcmBus("nosuchprovider://x"), LcmError);
}

}  // namespace
}  // namespace lidartag::daemon
