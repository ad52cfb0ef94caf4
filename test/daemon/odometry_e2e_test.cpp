// lidartagd's sensor pipeline with the robot's odometry, in process on memq:// (issue 33): a
// simulated VLP-16 yawing at 30 deg/s past two tags is written to a capture and replayed, while the
// simulator's own sensor poses are published as lidartag.ego_motion_t on the ego-motion channel.
// Each tag keeps one confirmed track whose position, placed in the odometry frame at each
// detection's own time, stays within 2 cm over the run (the target); the ego-motion
// counters of status_t add up; the deskew, turned on, moves the clusters with the same poses.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <thread>
#include <vector>

#include "../../bench/sim_scans.hpp"
#include "../temp_dir.hpp"
#include "lcm_bytes.hpp"
#include "lidartag/daemon/ego_motion_input.hpp"
#include "lidartag/daemon/messages.hpp"
#include "lidartag/daemon/sensor_pipeline.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/ego_motion_t.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
using lcm_test::decode;

constexpr int kRotations = 20;
const char* const kOdom = "ROBOT_ODOM";

// Two 1.2 m tag16h5 on easels: 10 m straight ahead and 7 m ahead, 3 m to the left; the sensor
// yawing at 30 deg/s (60 deg over the run: both stay in view).
sim::Scene turning_scene() {
  sim::Scene scene = eval::accuracy_scene(velodyne::Model::kVLP16, 10.0, 0, 3);
  sim::TagOptions second = scene.tags.front();
  second.id = 11;
  second.center = {7.0, 3.0, 1.0};
  const Eigen::Vector3d towards = -Eigen::Vector3d(7.0, 3.0, 0.0).normalized();
  second.normal = {towards.x(), towards.y(), 0.0};
  scene.tags.push_back(second);
  scene.sensor.angular_velocity = {0.0, 0.0, 30.0};
  return scene;
}

struct Capture {
  sim::Scene scene = turning_scene();
  std::string path;
  sim::Truth truth;
};

const Capture& capture() {
  static test::ProcessTempDir dir("lidartag-odometry");
  static const Capture c = [] {
    Capture out;
    out.path = dir.path() + "/turning.pcap";
    sim::Simulator simulator(out.scene);
    driver::PcapWriter writer(out.path);
    out.truth =
        simulator.run(kRotations, 17, [&](std::span<const uint8_t> p, int64_t t, uint16_t port) {
          writer.write_udp(p, t, port);
        });
    writer.close();
    return out;
  }();
  return c;
}

DaemonOptions odometry_options(bool odometry, bool deskew) {
  std::vector<std::string> overrides = {"sensors[0].model=vlp16",
                                        "sensors[0].source.kind=pcap",
                                        "sensors[0].source.file=" + capture().path,
                                        "sensors[0].source.rate=0",
                                        "lcm.url=memq://",
                                        "detector.tag_sizes_m=[1.2]"};
  if (odometry) overrides.push_back(std::string("ego_motion.channel=") + kOdom);
  if (deskew) overrides.push_back("detector.deskew.enabled=true");
  return parse_config("", overrides);
}

struct Recorder {
  std::vector<std::vector<uint8_t>> detections;
  void handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    if (channel != "LIDARTAG_DETECTIONS") return;
    const auto* p = static_cast<const uint8_t*>(rbuf->data);
    detections.emplace_back(p, p + rbuf->data_size);
  }
};

// The simulator's sensor poses, 100 Hz over the run and a little around it, as the robot's
// odometry (the body is the sensor: no mount), handed to `input` before the replay starts.
int publish_odometry(EgoMotionInput& input, const sim::Scene& scene) {
  const sim::Trajectory trajectory(scene.sensor);
  const auto t0 = static_cast<int64_t>(scene.sensor.start_time_s * 1e9);
  int sent = 0;
  for (int k = -5; k <= kRotations * 10 + 10; ++k) {
    const sim::Pose p = trajectory.at(0.01 * k);
    const Eigen::Quaterniond q(p.rotation);
    lidartag::ego_motion_t m;
    m.utime = (t0 + k * 10'000'000) / 1000;
    m.frame_id = "odom";
    m.child_frame_id = "velodyne";
    m.kind = lidartag::ego_motion_t::POSE;
    for (int i = 0; i < 3; ++i) m.position[i] = p.position[i];
    m.orientation[0] = q.w();
    m.orientation[1] = q.x();
    m.orientation[2] = q.y();
    m.orientation[3] = q.z();
    input.lcm().publish(kOdom, &m);
    ++sent;
  }
  for (int k = 0; k < 10 * sent && input.counts().received < static_cast<uint64_t>(sent); ++k)
    input.poll(0);
  return sent;
}

struct Replay {
  std::vector<lidartag::tag_detections_t> messages;
  SensorStatus status;
  lidartag::status_t status_message;
};

Replay run(const DaemonOptions& o) {
  LcmBus bus(o.lcm.url);
  Recorder recorder;
  bus.lcm().subscribe(".*", &Recorder::handle, &recorder);
  std::unique_ptr<EgoMotionInput> ego;
  if (!o.ego_motion.channel.empty()) {
    ego = std::make_unique<EgoMotionInput>(o.ego_motion, o.lcm.url, sensor_mounts(o));
    const int sent = publish_odometry(*ego, capture().scene);
    EXPECT_EQ(ego->counts().accepted, static_cast<uint64_t>(sent));
    bus.attach_ego_motion(ego.get());
  }
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 3);
  tbb::task_arena arena(2, 0);
  Replay out;
  {
    SensorPipeline pipeline(o.sensors[0], o, bus, arena, 2, nullptr, nullptr);
    pipeline.start();
    const auto deadline = std::chrono::steady_clock::now() + 120s;
    while (!pipeline.finished() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(10ms);
    EXPECT_TRUE(pipeline.finished());
    pipeline.join();
    out.status = pipeline.status(steady_ns());
  }
  while (bus.lcm().handleTimeout(0) > 0) {
  }
  fill_status(out.status, 0, 0.0, out.status_message);
  if (ego) {
    const EgoMotionState state = ego->state();
    fill_ego_status(&state, out.status_message);
  }
  for (const auto& bytes : recorder.detections)
    out.messages.push_back(decode<lidartag::tag_detections_t>(bytes));
  return out;
}

// Per tag (by ID): its tracks, and the track's position in the odometry frame at each detection's
// own time (the simulator's pose then: what the odometry says), from the 4th rotation on.
struct TagSeen {
  std::set<int> tracks;
  int rotations = 0, confirmed = 0;
  std::vector<Eigen::Vector3d> odometry;
  double spread_m() const {
    double most = 0.0;
    for (size_t i = 0; i < odometry.size(); ++i)
      for (size_t j = i + 1; j < odometry.size(); ++j)
        most = std::max(most, (odometry[i] - odometry[j]).norm());
    return most;
  }
};

std::map<int, TagSeen> score(const Replay& r) {
  const sim::Scene& scene = capture().scene;
  const sim::Trajectory trajectory(scene.sensor);
  const auto t0 = static_cast<int64_t>(scene.sensor.start_time_s * 1e9);
  std::map<int, TagSeen> seen;
  for (size_t k = 3; k < r.messages.size(); ++k) {
    for (const auto& d : r.messages[k].detections) {
      TagSeen& s = seen[d.id];
      s.tracks.insert(d.track_id);
      ++s.rotations;
      s.confirmed += d.confirmed ? 1 : 0;
      const double t_s =
          static_cast<double>(r.messages[k].utime * 1000 - t0) * 1e-9 + d.time_center_s;
      const sim::Pose then = trajectory.at(t_s);
      const Eigen::Vector3d p(d.track_position[0], d.track_position[1], d.track_position[2]);
      s.odometry.push_back(then.rotation * p + then.position);
    }
  }
  return seen;
}

TEST(DaemonOdometry, EachTagKeepsOneTrackConsistentInTheOdometryFrame) {
  const Replay with = run(odometry_options(true, false));
  const Replay without = run(odometry_options(false, false));
  ASSERT_GE(with.messages.size(), static_cast<size_t>(kRotations - 2));
  // The replay's stamps are the simulator's (the odometry's clock): each complete rotation is one
  // of the truth's, to within a column (55 us; the truth's rotation starts at the cut azimuth).
  const Capture& c = capture();
  int complete = 0;
  for (const auto& m : with.messages) {
    if (!m.complete) continue;
    ++complete;
    const bool found = std::any_of(c.truth.rotations.begin(), c.truth.rotations.end(),
                                   [&](const sim::RotationTruth& t) {
                                     return std::llabs(m.utime * 1000 - t.stamp_ns) < 100'000;
                                   });
    EXPECT_TRUE(found) << "rotation " << m.sequence << " stamped " << m.utime << " us";
  }
  EXPECT_GE(complete, kRotations - 3);
  const auto a = score(with), b = score(without);
  for (const int id : {3, 11}) {
    SCOPED_TRACE(id);
    ASSERT_TRUE(a.count(id));
    const TagSeen& s = a.at(id);
    const double spread_without = b.count(id) ? b.at(id).spread_m() : -1.0;
    std::printf(
        "tag %d: with odometry %d rotations, %zu track(s), %d confirmed, spread %.1f mm in the "
        "odometry frame; without: %zu track(s), spread %.1f mm\n",
        id, s.rotations, s.tracks.size(), s.confirmed, 1e3 * s.spread_m(),
        b.count(id) ? b.at(id).tracks.size() : 0u, 1e3 * spread_without);
    EXPECT_GE(s.rotations, kRotations - 5);
    EXPECT_EQ(s.tracks.size(), 1u);
    EXPECT_GE(s.confirmed, s.rotations - 2);
    EXPECT_LE(s.spread_m(), 0.02);
    // Without the odometry each tag keeps its track too (its own motion model), but its positions
    // placed in the odometry frame scatter more (about 5 mm against 2 here).
    ASSERT_TRUE(b.count(id));
    EXPECT_EQ(b.at(id).tracks.size(), 1u);
    EXPECT_LT(s.spread_m(), 0.75 * spread_without);
  }
  // The tracker placed its candidates with the poses; the counters of status_t add up.
  const lidartag::status_t& st = with.status_message;
  EXPECT_TRUE(st.ego_enabled);
  EXPECT_GT(st.ego_placed, 2 * (kRotations - 4));
  EXPECT_EQ(st.ego_missing, 0);
  EXPECT_EQ(st.ego_received, st.ego_accepted + st.ego_dropped);
  EXPECT_EQ(st.ego_dropped,
            st.ego_out_of_order + st.ego_invalid + st.ego_unknown_kind + st.ego_undecodable);
  EXPECT_EQ(st.ego_dropped, 0);
  EXPECT_EQ(st.ego_gaps, 0);
  EXPECT_GE(st.ego_age_s, 0.0);
  EXPECT_FALSE(without.status_message.ego_enabled);
  EXPECT_EQ(without.status_message.ego_placed, 0);
  EXPECT_EQ(without.status_message.ego_received, 0);
}

TEST(DaemonOdometry, TheDeskewMovesTheClustersWithTheOdometrysPoses) {
  const Replay r = run(odometry_options(true, true));
  const lidartag::status_t& st = r.status_message;
  EXPECT_GT(st.deskewed_ego, 2 * (kRotations - 4));
  EXPECT_EQ(st.deskew_without_motion, 0);
  const auto seen = score(r);
  for (const int id : {3, 11}) {
    SCOPED_TRACE(id);
    ASSERT_TRUE(seen.count(id));
    EXPECT_EQ(seen.at(id).tracks.size(), 1u);
    EXPECT_LE(seen.at(id).spread_m(), 0.02);
  }
  // Without odometry the tracker's model moves them once a track knows the motion.
  const Replay model = run(odometry_options(false, true));
  EXPECT_GT(model.status_message.deskewed_model, kRotations);
  EXPECT_EQ(model.status_message.deskewed_ego, 0);
}

}  // namespace
}  // namespace lidartag::daemon
