// The robot's motion on LCM (config ego_motion): messages moved from the body to the LiDAR by
// the mount, bad ones counted and dropped, the input's health note (nothing yet, stale, dropped),
// received over an in-process memq:// LCM.
#include "lidartag/daemon/ego_motion_input.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <thread>

#include "lidartag/daemon/lcm_url.hpp"

namespace lidartag::daemon {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int64_t kUtime0 = 1'700'000'000'000'000;  // microseconds

lidartag::ego_motion_t pose(int64_t utime, const Eigen::Vector3d& p, double yaw_rad) {
  lidartag::ego_motion_t m;
  m.utime = utime;
  m.frame_id = "odom";
  m.child_frame_id = "base_link";
  m.kind = lidartag::ego_motion_t::POSE;
  const Eigen::Quaterniond q(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  for (int i = 0; i < 3; ++i) m.position[i] = p[i];
  m.orientation[0] = q.w();
  m.orientation[1] = q.x();
  m.orientation[2] = q.y();
  m.orientation[3] = q.z();
  return m;
}

TEST(EgoMotionInput, ABodysPoseBecomesTheSensorsThroughTheMount) {
  BodyMount config;
  config.x = 0.5;  // the LiDAR 0.5 m ahead of the body's origin, 1 m up, turned 90 deg left
  config.z = 1.0;
  config.yaw_deg = 90.0;
  const SensorMount mount = sensor_mount(config);
  detector::EgoMotion ego;
  // The body at (10, 0, 0) facing +y.
  ASSERT_EQ(apply_ego_message(pose(kUtime0, {10.0, 0.0, 0.0}, kPi / 2), mount, ego),
            EgoMessage::kAccepted);
  detector::EgoPose p;
  ASSERT_EQ(ego.at(kUtime0 * 1000, p), detector::EgoLookup::kOk);
  EXPECT_NEAR((p.position - Eigen::Vector3d(10.0, 0.5, 1.0)).norm(), 0.0, 1e-12);
  // The sensor's x (its forward) points along the odometry's -x: body +y, turned 90 deg more.
  EXPECT_NEAR((p.orientation * Eigen::Vector3d::UnitX() - Eigen::Vector3d(-1, 0, 0)).norm(), 0.0,
              1e-12);
}

TEST(EgoMotionInput, ABodysTwistBecomesTheSensors) {
  BodyMount config;
  config.x = 1.0;  // a LiDAR 1 m ahead of a body turning in place sees itself move sideways
  const SensorMount mount = sensor_mount(config);
  detector::EgoMotion ego;
  lidartag::ego_motion_t m;
  m.kind = lidartag::ego_motion_t::TWIST;
  m.angular[2] = 0.1;  // rad/s
  for (int k = 0; k <= 10; ++k) {
    m.utime = kUtime0 + k * 10'000;
    ASSERT_EQ(apply_ego_message(m, mount, ego), EgoMessage::kAccepted);
  }
  detector::EgoPose p;
  ASSERT_EQ(ego.at((kUtime0 + 100'000) * 1000, p), detector::EgoLookup::kOk);
  // After 0.1 s: turned 0.01 rad, moved 1 m x 0.01 rad to its left.
  EXPECT_NEAR(p.position.y(), 0.01, 1e-5);
  EXPECT_NEAR(p.position.x(), 0.0, 1e-4);
  EXPECT_NEAR(Eigen::AngleAxisd(p.orientation).angle(), 0.01, 1e-9);
}

TEST(EgoMotionInput, BadMessagesAreDroppedAndNamed) {
  const SensorMount mount;
  detector::EgoMotion ego;
  ASSERT_EQ(apply_ego_message(pose(kUtime0, {0, 0, 0}, 0.0), mount, ego), EgoMessage::kAccepted);
  EXPECT_EQ(apply_ego_message(pose(kUtime0, {0, 0, 0}, 0.0), mount, ego), EgoMessage::kOutOfOrder);
  auto nan = pose(kUtime0 + 10, {0, 0, 0}, 0.0);
  nan.position[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(apply_ego_message(nan, mount, ego), EgoMessage::kInvalid);
  auto zero = pose(kUtime0 + 10, {0, 0, 0}, 0.0);
  zero.orientation[0] = 0.0;
  EXPECT_EQ(apply_ego_message(zero, mount, ego), EgoMessage::kInvalid);
  auto kind = pose(kUtime0 + 10, {0, 0, 0}, 0.0);
  kind.kind = 7;
  EXPECT_EQ(apply_ego_message(kind, mount, ego), EgoMessage::kUnknownKind);
  auto far = pose(std::numeric_limits<int64_t>::max(), {0, 0, 0}, 0.0);
  EXPECT_EQ(apply_ego_message(far, mount, ego), EgoMessage::kInvalid);
}

TEST(EgoMotionInput, ReceivesCountsAndSaysWhenStale) {
  EgoMotionConfig config;
  config.channel = "ROBOT_ODOM";
  config.stale_s = 0.2;
  EgoMotionInput input(config, "memq://");
  EXPECT_NE(input.health_note().find("nothing received on ROBOT_ODOM yet"), std::string::npos);
  for (int k = 0; k < 5; ++k) {
    const auto m = pose(kUtime0 + k * 10'000, {0.1 * k, 0.0, 0.0}, 0.0);
    input.lcm().publish("ROBOT_ODOM", &m);
  }
  const auto old = pose(kUtime0, {0, 0, 0}, 0.0);  // out of order
  input.lcm().publish("ROBOT_ODOM", &old);
  const char garbage[3] = {1, 2, 3};
  input.lcm().publish("ROBOT_ODOM", garbage, 3);
  for (int k = 0; k < 7; ++k) input.poll(10);
  const EgoMotionCounts c = input.counts();
  EXPECT_EQ(c.received, 7u);
  EXPECT_EQ(c.accepted, 5u);
  EXPECT_EQ(c.out_of_order, 1u);
  EXPECT_EQ(c.undecodable, 1u);
  input.read([](const detector::EgoMotion& ego) {
    detector::EgoPose p;
    ASSERT_EQ(ego.at((kUtime0 + 25'000) * 1000, p), detector::EgoLookup::kOk);
    EXPECT_NEAR(p.position.x(), 0.25, 1e-12);
  });
  std::string note = input.health_note();
  EXPECT_EQ(note.find("stale"), std::string::npos) << note;
  EXPECT_NE(note.find("2 of 7 messages dropped (1 out of order, 0 invalid, 0 of unknown kind, 1 "
                      "undecodable)"),
            std::string::npos)
      << note;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  note = input.health_note();
  EXPECT_NE(note.find("stale, nothing on ROBOT_ODOM for"), std::string::npos) << note;
  // The thread receives too, and stops.
  input.start();
  const auto late = pose(kUtime0 + 100'000, {1.0, 0.0, 0.0}, 0.0);
  input.lcm().publish("ROBOT_ODOM", &late);
  for (int k = 0; k < 100 && input.counts().accepted < 6; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(input.counts().accepted, 6u);
  input.stop();
}

// One message, one pose per sensor, each through its own mount (sensors[].sensor_in_body).
TEST(EgoMotionInput, EachSensorGetsTheBodysPoseThroughItsOwnMount) {
  DaemonOptions options = parse_config(
      "sensors: [{name: front, sensor_in_body: {x: 1.0}}, {name: rear, channel_prefix: R_}]\n"
      "ego_motion: {channel: ROBOT_ODOM, sensor_in_body: {x: -1.0, yaw_deg: 180}}");
  EgoMotionInput input(options.ego_motion, "memq://", sensor_mounts(options));
  EXPECT_EQ(input.sensors(), 2u);
  const auto m = pose(kUtime0, {10.0, 0.0, 0.0}, 0.0);
  input.lcm().publish("ROBOT_ODOM", &m);
  input.poll(10);
  EXPECT_EQ(input.counts().accepted, 1u);
  const int64_t t_ns = kUtime0 * 1000;
  detector::EgoPose front, rear;
  input.read(0, [&](const detector::EgoMotion& e) {
    ASSERT_EQ(e.at(t_ns, front), detector::EgoLookup::kOk);
  });
  input.read(1, [&](const detector::EgoMotion& e) {
    ASSERT_EQ(e.at(t_ns, rear), detector::EgoLookup::kOk);
  });
  EXPECT_NEAR((front.position - Eigen::Vector3d(11.0, 0.0, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((rear.position - Eigen::Vector3d(9.0, 0.0, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(front.orientation.angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
  EXPECT_NEAR(rear.orientation.angularDistance(Eigen::Quaterniond::Identity()), kPi, 1e-9);
}

// The counters of status_t: received = accepted + dropped, dropped by reason; gaps between
// accepted stamps; stale episodes and the age of the last message.
TEST(EgoMotionInput, CountersAddUpAndCountGapsAndStaleEpisodes) {
  EgoMotionConfig config;
  config.channel = "ROBOT_ODOM";
  config.stale_s = 0.05;
  config.buffer.max_gap_s = 0.2;
  EgoMotionInput input(config, "memq://");
  EXPECT_LT(input.state().age_s, 0.0);
  auto send = [&](const lidartag::ego_motion_t& m) {
    input.lcm().publish("ROBOT_ODOM", &m);
    input.poll(10);
  };
  send(pose(kUtime0, {0, 0, 0}, 0.0));
  send(pose(kUtime0 + 10'000, {0, 0, 0}, 0.0));
  send(pose(kUtime0 + 510'000, {0, 0, 0}, 0.0));  // 0.5 s later: a gap
  send(pose(kUtime0 + 5'000, {0, 0, 0}, 0.0));    // out of order
  auto bad = pose(kUtime0 + 600'000, {0, 0, 0}, 0.0);
  bad.orientation[0] = 3.0;  // no rotation
  send(bad);
  auto odd = pose(kUtime0 + 600'000, {0, 0, 0}, 0.0);
  odd.kind = 9;
  send(odd);
  const char garbage[2] = {0, 1};
  input.lcm().publish("ROBOT_ODOM", garbage, 2);
  input.poll(10);
  EgoMotionState s = input.state();
  EXPECT_EQ(s.counts.received, 7u);
  EXPECT_EQ(s.counts.accepted, 3u);
  EXPECT_EQ(s.counts.out_of_order, 1u);
  EXPECT_EQ(s.counts.invalid, 1u);
  EXPECT_EQ(s.counts.unknown_kind, 1u);
  EXPECT_EQ(s.counts.undecodable, 1u);
  EXPECT_EQ(s.counts.dropped(), 4u);
  EXPECT_EQ(s.counts.received, s.counts.accepted + s.counts.dropped());
  EXPECT_EQ(s.counts.gaps, 1u);
  EXPECT_GE(s.age_s, 0.0);
  // Quiet past stale_s twice, with a message between: two episodes.
  EXPECT_EQ(s.counts.stale_episodes, 0u);
  std::this_thread::sleep_for(std::chrono::milliseconds(80));
  input.poll(1);
  s = input.state();
  EXPECT_TRUE(s.stale);
  EXPECT_EQ(s.counts.stale_episodes, 1u);
  send(pose(kUtime0 + 520'000, {0, 0, 0}, 0.0));
  EXPECT_FALSE(input.state().stale);
  std::this_thread::sleep_for(std::chrono::milliseconds(80));
  input.poll(1);
  EXPECT_EQ(input.state().counts.stale_episodes, 2u);
}

TEST(EgoMotionInput, ALogFileIsNoPlaceToReceiveFrom) {
  EgoMotionConfig config;
  config.channel = "ROBOT_ODOM";
  try {
    EgoMotionInput input(config, "file:///tmp/lidartag-out.lcmlog?mode=w");
    FAIL() << "accepted";
  } catch (const LcmError& e) {
    EXPECT_NE(std::string(e.what()).find("set ego_motion.url"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lidartag::daemon
