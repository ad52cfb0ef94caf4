// Health states from counters and clocks: each state from the situation it names, the most severe
// first, rates over windows, and healthy only when packets arrive, rotations come at the sensor's
// rate and publishes succeed.
#include "lidartag/daemon/health.hpp"

#include <gtest/gtest.h>

namespace lidartag::daemon {
namespace {

constexpr int64_t kSecond = 1'000'000'000;

// A VLP-32C at 600 rpm, 1 s after the start: 1507 packets and 10 rotations a second.
struct Sensor {
  HealthSample s;
  Sensor() {
    s.started_ns = 100 * kSecond;
    s.now_ns = s.started_ns + kSecond;
    s.data_port = 2368;
    s.data_packets = s.decoded = 1507;
    s.last_data_ns = s.now_ns;
    s.rotations = 10;
    s.sensor_ns = 1'700'000'000 * kSecond;
    s.rpm = 600;
    s.senders = {0xC0A801C9};
  }
  // `seconds` more of a normal stream.
  HealthSample& run(double seconds) {
    const auto dt = static_cast<int64_t>(seconds * 1e9);
    s.now_ns += dt;
    s.last_data_ns = s.now_ns;
    const auto packets = static_cast<uint64_t>(1507 * seconds);
    s.data_packets += packets;
    s.decoded += packets;
    s.rotations += static_cast<uint64_t>(10 * seconds);
    s.sensor_ns += dt;
    return s;
  }
};

Health judge(HealthMonitor& m, Sensor& sensor, int windows, double seconds = 2.0) {
  Health h;
  for (int i = 0; i < windows; ++i) h = m.update(sensor.run(seconds));
  return h;
}

TEST(Health, ANormalStreamIsHealthy) {
  HealthMonitor m({});
  Sensor sensor;
  const Health h = judge(m, sensor, 3);
  EXPECT_EQ(h.state, HealthState::kHealthy) << h.reason;
  EXPECT_TRUE(h.healthy());
  EXPECT_EQ(h.reason, "");
}

TEST(Health, NoPacketsIsWaitingWithinTheGraceThenSilent) {
  HealthOptions o;
  o.startup_grace_s = 10;
  HealthMonitor m(o);
  HealthSample s;
  s.started_ns = 5 * kSecond;
  s.data_port = 2368;
  s.now_ns = s.started_ns + 3 * kSecond;
  Health h = m.update(s);
  EXPECT_EQ(h.state, HealthState::kWaiting);
  EXPECT_FALSE(h.healthy());
  EXPECT_NE(h.reason.find("waiting for packets on port 2368"), std::string::npos) << h.reason;
  s.now_ns = s.started_ns + 11 * kSecond;
  h = m.update(s);
  EXPECT_EQ(h.state, HealthState::kSilent);
  EXPECT_NE(h.reason.find("no packets on port 2368 in the 11 s since the start"), std::string::npos)
      << h.reason;
}

TEST(Health, ASensorThatStopsSendingIsSilent) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 2);
  sensor.s.now_ns += kSecond;  // a second without a packet
  const Health h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kSilent);
  EXPECT_NE(h.reason.find("no packets on port 2368 for 1.0 s"), std::string::npos) << h.reason;
}

TEST(Health, LossAboveTheThresholdIsPacketLoss) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 2);
  sensor.s.missing += 20;  // 20 of ~3034 (0.7 %): below 1 %
  Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kHealthy) << h.reason;
  sensor.s.missing += 100;  // 3.2 %
  h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kPacketLoss);
  EXPECT_NE(h.reason.find("% of the data packets missing"), std::string::npos) << h.reason;
  // The verdict holds until the next window closes, then clears.
  h = m.update(sensor.run(0.5));
  EXPECT_EQ(h.state, HealthState::kPacketLoss);
  h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kHealthy) << h.reason;
}

TEST(Health, SpoofedPacketsMultiplyingRotationsAreImplausible) {
  // The attack: 20 % stray packets made 1,200 "rotations" a second at "600 rpm".
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  sensor.s.rotations += 2400;
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kRateImplausible);
  EXPECT_NE(h.reason.find("stray or spoofed packets"), std::string::npos) << h.reason;
}

TEST(Health, RotationRateIsJudgedOnTheSensorsClock) {
  // A replay at full speed: 100 rotations in 0.5 s of wall time are 10 s of the sensor's.
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  for (int i = 0; i < 3; ++i) {
    sensor.s.now_ns += kSecond / 2;
    sensor.s.last_data_ns = sensor.s.now_ns;
    sensor.s.decoded += 15070;
    sensor.s.data_packets += 15070;
    sensor.s.rotations += 100;
    sensor.s.sensor_ns += 10 * kSecond;
    m.update(sensor.s);
  }
  const Health h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kHealthy) << h.reason;
}

TEST(Health, StrayPacketsDroppedAsInconsistentAreReported) {
  // What the batcher does with spoofed azimuths: dropped, counted; the status must say so.
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  sensor.s.inconsistent += 600;
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kSeveralSources);
  EXPECT_NE(h.reason.find("600 data packets"), std::string::npos) << h.reason;
  EXPECT_NE(h.reason.find("spoofed"), std::string::npos) << h.reason;
}

TEST(Health, AnImpossibleRpmIsImplausible) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.rpm = 2400;
  const Health h = judge(m, sensor, 2);
  EXPECT_EQ(h.state, HealthState::kRateImplausible);
  EXPECT_NE(h.reason.find("2400 rpm"), std::string::npos) << h.reason;
}

TEST(Health, PacketsWithoutRotationsAreImplausible) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  HealthSample& s = sensor.run(2.0);
  s.rotations -= 20;  // packets decoded, no rotation ended
  const Health h = m.update(s);
  EXPECT_EQ(h.state, HealthState::kRateImplausible);
  EXPECT_NE(h.reason.find("no rotation ended"), std::string::npos) << h.reason;
}

TEST(Health, DroppedRotationsAreFallingBehind) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  sensor.s.dropped_behind += 3;
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kFallingBehind);
  EXPECT_NE(h.reason.find("3 rotations dropped"), std::string::npos) << h.reason;
}

TEST(Health, RisingPublishFailuresArePublishFailing) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.publish_failures = 7;  // before the first window: history, not news
  judge(m, sensor, 2);
  EXPECT_EQ(judge(m, sensor, 1).state, HealthState::kHealthy);
  sensor.s.publish_failures += 1;
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kPublishFailing);
  EXPECT_NE(h.reason.find("1 LCM message not published"), std::string::npos) << h.reason;
}

// The size check: detections whose points measure another size than configured make the state
// "tag size mismatch" (a biased pose is not all well), with the tag and both sizes; below every
// data-path problem; and the final status of a replay names it.
TEST(Health, DetectionsOfTheWrongSizeAreATagSizeMismatch) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 2);
  sensor.s.size_warnings = 9;
  sensor.s.size_note = "tag16h5 id 0 measures 0.800 m, configured 0.750 m";
  Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kTagSizeMismatch);
  EXPECT_FALSE(h.healthy());
  EXPECT_EQ(health_state_name(h.state), "tag size mismatch");
  EXPECT_NE(h.reason.find("9 detections in the last 2.0 s measure another size than configured: "
                          "tag16h5 id 0 measures 0.800 m, configured 0.750 m"),
            std::string::npos)
      << h.reason;
  // No new warning in a window: healthy again.
  EXPECT_EQ(judge(m, sensor, 1).state, HealthState::kHealthy);
  // Dropped rotations are more severe; both are in the reason.
  sensor.s.size_warnings += 1;
  sensor.s.dropped_behind += 2;
  h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kFallingBehind);
  EXPECT_NE(h.reason.find("1 detection in the last"), std::string::npos) << h.reason;
  sensor.s.ended = true;
  h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kEnded);
  EXPECT_NE(h.reason.find("10 detections measured another size than configured: tag16h5 id 0"),
            std::string::npos)
      << h.reason;
}

TEST(Health, ModelProblemsAreModelMismatch) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  sensor.s.model_problem = "configured model vlp32c does not fit the packets";
  Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kModelMismatch);
  EXPECT_EQ(h.reason, sensor.s.model_problem);
  // Packets of another model mid-stream, as the driver counts them.
  sensor.s.model_problem.clear();
  sensor.s.model_mismatch += 500;
  h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kModelMismatch);
  EXPECT_NE(h.reason.find("500 data packets"), std::string::npos) << h.reason;
  // With the capture reader's own account of it.
  sensor.s.model_mismatch += 64;
  sensor.s.model_note = "model changed mid-stream: vlp32c -> vlp16";
  h = judge(m, sensor, 1);
  EXPECT_NE(h.reason.find("64 data packets in the last 2.0 s do not fit the model decoded: model "
                          "changed mid-stream: vlp32c -> vlp16"),
            std::string::npos)
      << h.reason;
  // Once no packet contradicts the model any more, the window clears.
  EXPECT_EQ(judge(m, sensor, 1).state, HealthState::kHealthy);
}

TEST(Health, TwoSendersOnOnePortSayWhichAndHowToSeparateThem) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.senders = {0xC0A801C9, 0xC0A801CA};
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kSeveralSources);
  EXPECT_NE(h.reason.find("192.168.1.201, 192.168.1.202 on port 2368"), std::string::npos)
      << h.reason;
  EXPECT_NE(h.reason.find("sensors[].source.sensor_address"), std::string::npos);
}

TEST(Health, TheMostSevereProblemIsTheStateAndEveryOneIsInTheReason) {
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 1);
  sensor.s.dropped_behind += 1;
  sensor.s.missing += 200;
  sensor.s.stall = "no rotation published for 4.0 s with 3 in the pipeline";
  const Health h = judge(m, sensor, 1);
  EXPECT_EQ(h.state, HealthState::kStalled);
  const auto stalled = h.reason.find("no rotation published");
  const auto behind = h.reason.find("rotation dropped");
  const auto loss = h.reason.find("missing");
  ASSERT_NE(stalled, std::string::npos) << h.reason;
  ASSERT_NE(behind, std::string::npos) << h.reason;
  ASSERT_NE(loss, std::string::npos) << h.reason;
  EXPECT_LT(stalled, behind);
  EXPECT_LT(behind, loss);
  sensor.s.error = "calibration does not fit";
  EXPECT_EQ(m.update(sensor.s).state, HealthState::kError);
}

TEST(Health, TheFinalStatusNamesWhatWentWrongOverTheWholeRun) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.ended = true;
  sensor.s.data_packets = 24117;  // e.g. VLS-128 packets decoded as a VLP-32C: none decodes
  sensor.s.decoded = 0;
  Health h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kEnded);
  EXPECT_NE(h.reason.find("none of its 24117 data packets could be decoded"), std::string::npos)
      << h.reason;
  sensor.s.decoded = 24117;
  sensor.s.publish_failures = 3;
  h = m.update(sensor.s);
  EXPECT_EQ(h.reason, "the source ended; 3 LCM messages not published");
  sensor.s.publish_failures = 0;
  h = m.update(sensor.s);
  EXPECT_EQ(h.reason, "the source ended");
}

TEST(Health, PacketsThatArriveButNeverDecodeAreNotHealthy) {
  // Junk before the sensor once stopped all decoding while every flag said healthy: packets
  // arrive, the sender is one, nothing is silent or lost. Progress decides.
  HealthMonitor m({});
  Sensor sensor;
  judge(m, sensor, 2);
  Health h;
  for (int i = 0; i < 2; ++i) {
    sensor.s.now_ns += 2 * kSecond;
    sensor.s.last_data_ns = sensor.s.now_ns;
    sensor.s.data_packets += 3014;
    sensor.s.malformed += 3014;
    h = m.update(sensor.s);
  }
  EXPECT_EQ(h.state, HealthState::kNotDecoding) << h.reason;
  EXPECT_FALSE(h.healthy());
  EXPECT_NE(h.reason.find("3014 data packets on port 2368 in the last 2.0 s, none decoded"),
            std::string::npos)
      << h.reason;
  // Decoding again: healthy once a window has passed.
  judge(m, sensor, 2);
  EXPECT_EQ(m.update(sensor.run(2.0)).state, HealthState::kHealthy);
}

TEST(Health, AStoppedRunStillNamesWhatWentWrong) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.ended = true;
  sensor.s.stopped = true;
  EXPECT_EQ(m.update(sensor.s).reason, "stopped");
  sensor.s.decoded = 0;
  const Health h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kEnded);
  EXPECT_EQ(h.reason.rfind("stopped; none of its 1507 data packets could be decoded", 0), 0u)
      << h.reason;
}

TEST(Health, AReplayWithoutDataPacketsSaysWhatCameInstead) {
  HealthMonitor m({});
  HealthSample s;
  s.ended = true;
  s.data_port = 2368;
  s.malformed = 5;
  s.ignored = 7;
  EXPECT_EQ(m.update(s).reason,
            "the source ended; no data packet on port 2368: 5 malformed or cut short, 7 on other "
            "ports or not IPv4/UDP");
  s.source_error = "capture 'x.pcap' is unreadable after record 99 (bad header)";
  EXPECT_EQ(m.update(s).reason.rfind("the source ended; capture 'x.pcap' is unreadable after "
                                     "record 99 (bad header); no data packet",
                                     0),
            0u)
      << m.update(s).reason;
}

TEST(Health, AnEndedSourceIsEndedOrItsError) {
  HealthMonitor m({});
  Sensor sensor;
  sensor.s.ended = true;
  EXPECT_EQ(m.update(sensor.s).state, HealthState::kEnded);
  sensor.s.error = "bad calibration";
  const Health h = m.update(sensor.s);
  EXPECT_EQ(h.state, HealthState::kError);
  EXPECT_EQ(h.reason, "bad calibration");
}

}  // namespace
}  // namespace lidartag::daemon
