// One sensor's pipeline in process (memq://) on synthetic streams written to pcaps, damaged on
// purpose: every counter says what happened, once, and the rotations add up at every status
// (assembled = published + dropped + in flight; exactly at the end) under loss, duplicates,
// reordering, junk, spoofed packets, a second sender, a wrong model, a silent sensor and a slow
// detector.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <random>
#include <thread>

#include "driver/synthetic_stream.hpp"
#include "lcm_bytes.hpp"
#include "lidartag/daemon/sensor_pipeline.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
using velodyne::Model;
using velodyne::ReturnMode;
using Stream = std::vector<velodyne::testing::StreamPacket>;

// oneTBB fixes its largest worker pool when the process first uses it (the machine's cores less
// one unless a global_control allows more); the pipelines below use up to 3 workers whatever the
// machine and whatever ran before, so the whole test program allows 4 threads from the start.
class TbbThreads : public ::testing::Environment {
 public:
  void SetUp() override {
    control_ =
        std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 4);
  }
  void TearDown() override { control_.reset(); }

 private:
  std::unique_ptr<tbb::global_control> control_;
};
[[maybe_unused]] ::testing::Environment* const kTbbThreads =
    ::testing::AddGlobalTestEnvironment(new TbbThreads);

constexpr uint32_t kSensorA = 0xC0A801C9;  // 192.168.1.201
constexpr uint32_t kSensorB = 0xC0A801CA;  // 192.168.1.202

struct Packet {
  std::vector<uint8_t> bytes;
  int64_t time_ns;
  uint32_t source = kSensorA;
};

std::vector<Packet> packets_of(const Stream& stream, uint32_t source = kSensorA) {
  std::vector<Packet> out;
  for (const auto& p : stream) out.push_back({p.bytes, p.time_ns, source});
  return out;
}

// `seconds` of a sensor at 600 rpm.
Stream sensor_stream(Model model, double seconds, velodyne::testing::StreamOptions o = {}) {
  const auto& spec = velodyne::model_spec(model);
  const int n = static_cast<int>(seconds * spec.packet_rate_hz(ReturnMode::kStrongest));
  return velodyne::testing::make_stream(spec, ReturnMode::kStrongest, n, o);
}

std::string write_pcap(const std::vector<Packet>& packets, const std::string& name) {
  const std::string path = ::testing::TempDir() + "/lidartag_counters_" +
                           std::to_string(::getpid()) + "_" + name + ".pcap";
  driver::PcapWriter writer(path);
  for (const auto& p : packets) {
    writer.write_udp(p.bytes, p.time_ns, velodyne::kDefaultDataPort, p.source);
  }
  writer.close();
  return path;
}

void expect_adds_up(const SensorStatus& s) {
  EXPECT_EQ(s.rotations_assembled,
            s.rotations_published + s.rotations_dropped + s.rotations_in_flight);
  EXPECT_EQ(s.rotations_dropped, s.rotations_behind + s.rotations_seam + s.rotations_unsent);
}

struct Outcome {
  std::vector<SensorStatus> statuses;  // taken while it ran, then the final one
  std::vector<lidartag::tag_detections_t> detections;
  const SensorStatus& last() const { return statuses.back(); }
  // Did any status while running have this state?
  bool saw(HealthState state) const {
    return std::any_of(statuses.begin(), statuses.end(),
                       [&](const SensorStatus& s) { return s.health.state == state; });
  }
  std::string reasons() const {
    std::string all;
    for (const auto& s : statuses) {
      all += std::string(health_state_name(s.health.state)) + ": " + s.health.reason + "\n";
    }
    return all;
  }
};

struct Collector {
  std::vector<std::vector<uint8_t>> messages;
  void handle(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const auto* p = static_cast<const uint8_t*>(rbuf->data);
    messages.emplace_back(p, p + rbuf->data_size);
  }
};

// Runs the pcap through a SensorPipeline (two workers), taking a status every `poll` and checking
// the rotation invariant at each; then checks it exactly at the end.
Outcome run_pcap(const std::string& pcap, std::vector<std::string> settings,
                 SensorPipeline::DetectHook hook = {}, std::chrono::milliseconds poll = 20ms,
                 int workers = 2) {
  std::vector<std::string> all = {"sensors[0].source.kind=pcap", "sensors[0].source.file=" + pcap,
                                  "sensors[0].source.rate=0", "lcm.url=memq://",
                                  "health.window_s=0.2"};
  all.insert(all.end(), settings.begin(), settings.end());
  const DaemonOptions options = parse_config("", all);
  LcmBus bus(options.lcm.url);
  Collector collector;
  bus.lcm().subscribe("LIDARTAG_DETECTIONS", &Collector::handle, &collector);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<size_t>(workers + 1));
  tbb::task_arena arena(workers, 0);
  Outcome run;
  {
    SensorPipeline pipeline(options.sensors[0], options, bus, arena, workers, nullptr, nullptr,
                            hook);
    pipeline.start();
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (!pipeline.finished() && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(poll);
      run.statuses.push_back(pipeline.status(steady_ns()));
      expect_adds_up(run.statuses.back());
    }
    EXPECT_TRUE(pipeline.finished());
    pipeline.join();
    run.statuses.push_back(pipeline.status(steady_ns()));
  }
  while (bus.lcm().handleTimeout(0) > 0) {
  }
  for (const auto& m : collector.messages) {
    run.detections.push_back(lcm_test::decode<lidartag::tag_detections_t>(m));
  }
  // Exactly at the end: nothing in flight; every rotation published is one message, in order;
  // the sequence numbers missing are the rotations dropped.
  const SensorStatus& last = run.last();
  expect_adds_up(last);
  EXPECT_EQ(last.rotations_in_flight, 0u);
  EXPECT_EQ(last.rotations_published, run.detections.size());
  int64_t previous = -1;
  for (const auto& d : run.detections) {
    EXPECT_GT(d.sequence, previous);
    previous = d.sequence;
  }
  EXPECT_LT(previous, static_cast<int64_t>(last.rotations_assembled));
  EXPECT_EQ(last.health.state, HealthState::kEnded);
  std::filesystem::remove(pcap);
  return run;
}

const Stream& clean_stream() {
  static const Stream s = sensor_stream(Model::kVLP32C, 1.0);
  return s;
}

TEST(Counters, ACleanStreamCountsNothingBad) {
  const Outcome run = run_pcap(write_pcap(packets_of(clean_stream()), "clean"), {});
  const SensorStatus& s = run.last();
  EXPECT_EQ(s.packets_data, clean_stream().size());
  EXPECT_EQ(s.packets_decoded, clean_stream().size());
  EXPECT_EQ(s.packets_received, clean_stream().size());
  for (uint64_t bad : {s.packets_kernel_dropped, s.packets_missing, s.packets_duplicate,
                       s.packets_reordered, s.packets_malformed, s.packets_foreign,
                       s.packets_inconsistent, s.packets_model_mismatch, s.packets_ignored}) {
    EXPECT_EQ(bad, 0u);
  }
  EXPECT_EQ(s.rotations_assembled, 11u);  // 10 deg -> 180, ten turns, the rest: 1 + 9 + 1
  EXPECT_EQ(s.rotations_published, 11u);
  EXPECT_EQ(s.rotations_dropped, 0u);
  EXPECT_EQ(s.model, "vlp32c");
}

TEST(Counters, LossIsCountedOnceAsMissingPackets) {
  auto packets = packets_of(clean_stream());
  std::mt19937 rng(7);
  size_t removed = 0;
  for (size_t i = 100; i + 40 < packets.size() && removed < 30; i += 20 + rng() % 20) {
    packets.erase(packets.begin() + static_cast<std::ptrdiff_t>(i));
    ++removed;
  }
  const Outcome run = run_pcap(write_pcap(packets, "loss"), {});
  const SensorStatus& s = run.last();
  EXPECT_EQ(s.packets_missing, removed);
  EXPECT_EQ(s.packets_kernel_dropped, 0u);  // a capture: nothing lost in this host
  EXPECT_EQ(s.packets_data, clean_stream().size() - removed);
  EXPECT_EQ(s.packets_duplicate + s.packets_reordered, 0u);
  EXPECT_EQ(s.rotations_published, s.rotations_assembled);
}

TEST(Counters, DuplicatesAreCountedAndNothingElseChanges) {
  auto packets = packets_of(clean_stream());
  size_t inserted = 0;
  for (size_t i = 50; i < packets.size() && inserted < 20; i += 70) {
    packets.insert(packets.begin() + static_cast<std::ptrdiff_t>(i + 1), packets[i]);
    ++inserted;
  }
  const Outcome run = run_pcap(write_pcap(packets, "duplicates"), {});
  const SensorStatus& s = run.last();
  // Told apart from reordering by the batcher (BatcherStats::duplicates); each counted once.
  EXPECT_EQ(s.packets_duplicate + s.packets_reordered, inserted);
  EXPECT_EQ(s.packets_missing, 0u);
  EXPECT_EQ(s.packets_data, clean_stream().size() + inserted);
  EXPECT_EQ(s.rotations_published, 11u);
}

TEST(Counters, ReorderedPacketsAreCounted) {
  auto packets = packets_of(clean_stream());
  size_t swapped = 0;
  for (size_t i = 60; i + 1 < packets.size() && swapped < 15; i += 80) {
    std::swap(packets[i], packets[i + 1]);
    ++swapped;
  }
  const Outcome run = run_pcap(write_pcap(packets, "reorder"), {});
  const SensorStatus& s = run.last();
  EXPECT_EQ(s.packets_duplicate + s.packets_reordered, swapped);
  EXPECT_EQ(s.packets_data, clean_stream().size());
  EXPECT_EQ(s.rotations_published, s.rotations_assembled);
}

TEST(Counters, JunkIsMalformedAndChangesNothingElse) {
  const Outcome clean = run_pcap(write_pcap(packets_of(clean_stream()), "junk_ref"), {});
  auto packets = packets_of(clean_stream());
  std::mt19937 rng(3);
  size_t junk = 0;
  for (size_t i = 200; i < packets.size() && junk < 40; i += 30) {
    Packet p{std::vector<uint8_t>(junk % 4 == 0 ? 100 : velodyne::kDataPacketSize),
             packets[i].time_ns + 1000};
    for (auto& b : p.bytes) b = static_cast<uint8_t>(rng());
    p.bytes[0] = 0x12;  // never a block flag
    packets.insert(packets.begin() + static_cast<std::ptrdiff_t>(i + 1), p);
    ++junk;
  }
  const Outcome run = run_pcap(write_pcap(packets, "junk"), {});
  const SensorStatus& s = run.last();
  EXPECT_EQ(s.packets_malformed, junk);
  EXPECT_EQ(s.packets_decoded, clean_stream().size());
  EXPECT_EQ(s.packets_missing, 0u);
  ASSERT_EQ(run.detections.size(), clean.detections.size());
  for (size_t i = 0; i < run.detections.size(); ++i) {
    EXPECT_EQ(run.detections[i].sequence, clean.detections[i].sequence);
    EXPECT_EQ(run.detections[i].columns, clean.detections[i].columns);
    EXPECT_EQ(run.detections[i].points, clean.detections[i].points);
  }
}

TEST(Counters, SpoofedPacketsNeverLeaveTheStatusHealthy) {
  // The attack: one well-formed packet in five with random in-range azimuths (its time
  // in sequence). Cut on, they multiply rotations (rate implausible); dropped, they are counted
  // as inconsistent (several sources). Either way the status says so, and adds up.
  auto mixed = packets_of(sensor_stream(Model::kVLP32C, 3.0));
  std::mt19937 rng(11);
  for (size_t i = 4; i < mixed.size(); i += 5) {
    for (size_t b = 0; b < velodyne::kBlocks; ++b) {
      velodyne::write_u16(mixed[i].bytes.data() + b * velodyne::kBlockSize + 2,
                          static_cast<uint16_t>(rng() % 36000));
    }
  }
  const Outcome run = run_pcap(write_pcap(mixed, "spoofed"), {"sensors[0].source.rate=1"});
  EXPECT_TRUE(run.saw(HealthState::kRateImplausible) || run.saw(HealthState::kSeveralSources))
      << run.reasons();
  // Once the first windows have closed (0.2 s each), never healthy.
  size_t healthy = 0;
  for (size_t i = 25; i < run.statuses.size(); ++i) {
    healthy += run.statuses[i].health.healthy() ? 1u : 0u;
  }
  EXPECT_GT(run.statuses.size(), 100u);  // 3 s at 20 ms
  EXPECT_EQ(healthy, 0u) << run.reasons();
}

TEST(Counters, TwoSendersOnOnePortAreNamedWithTheWayToSeparateThem) {
  velodyne::testing::StreamOptions other;
  other.start_azimuth_deg = 200;
  other.start_ns += 20'000;
  auto a = packets_of(sensor_stream(Model::kVLP32C, 1.0), kSensorA);
  auto b = packets_of(sensor_stream(Model::kVLP32C, 1.0, other), kSensorB);
  std::vector<Packet> both(a.begin(), a.end());
  both.insert(both.end(), b.begin(), b.end());
  std::stable_sort(both.begin(), both.end(),
                   [](const Packet& x, const Packet& y) { return x.time_ns < y.time_ns; });
  const Outcome run = run_pcap(write_pcap(both, "two_senders"), {"sensors[0].source.rate=1"});
  ASSERT_TRUE(run.saw(HealthState::kSeveralSources)) << run.reasons();
  EXPECT_NE(run.reasons().find("192.168.1.201, 192.168.1.202 on port 2368"), std::string::npos)
      << run.reasons();
  EXPECT_NE(run.reasons().find("sensors[].source.sensor_address"), std::string::npos);
  const auto with_two = std::find_if(run.statuses.begin(), run.statuses.end(),
                                     [](const SensorStatus& s) { return s.senders.size() == 2; });
  EXPECT_NE(with_two, run.statuses.end());
}

TEST(Counters, AConfiguredModelThatDoesNotFitIsReported) {
  const auto packets = packets_of(sensor_stream(Model::kVLP16, 1.0));
  const Outcome run = run_pcap(write_pcap(packets, "wrong_model"),
                               {"sensors[0].model=vlp32c", "sensors[0].source.rate=2"});
  ASSERT_TRUE(run.saw(HealthState::kModelMismatch)) << run.reasons();
  EXPECT_NE(run.reasons().find("configured model vlp32c does not fit the packets (their timing "
                               "is that of a vlp16)"),
            std::string::npos)
      << run.reasons();
}

TEST(Counters, AModelChangeMidStreamIsReported) {
  auto packets = packets_of(sensor_stream(Model::kVLP32C, 0.5));
  velodyne::testing::StreamOptions later;
  later.start_ns = packets.back().time_ns + 1'000'000;
  const auto vlp16 = packets_of(sensor_stream(Model::kVLP16, 1.0, later));
  packets.insert(packets.end(), vlp16.begin(), vlp16.end());
  const Outcome run = run_pcap(write_pcap(packets, "model_change"), {"sensors[0].source.rate=2"});
  const auto first = std::find_if(run.statuses.begin(), run.statuses.end(),
                                  [](const SensorStatus& s) { return !s.model.empty(); });
  ASSERT_NE(first, run.statuses.end());
  EXPECT_EQ(first->model, "vlp32c");
  // Whether the reader goes on decoding as the first packets said (the timing then contradicts
  // it) or follows the change (its count of contradicting packets rises), the status says so and
  // names the new model.
  ASSERT_TRUE(run.saw(HealthState::kModelMismatch)) << run.reasons();
  EXPECT_NE(run.reasons().find("vlp16"), std::string::npos) << run.reasons();
}

TEST(Counters, ASensorThatFallsSilentIsReportedAndItsRotationDelivered) {
  // 0.5 s of packets, 1.5 s of silence, 0.5 s more, replayed at the recorded pace.
  auto packets = packets_of(sensor_stream(Model::kVLP32C, 0.5));
  velodyne::testing::StreamOptions later;
  later.start_ns = packets.back().time_ns + 1'500'000'000;
  later.start_azimuth_deg = 100;
  const auto rest = packets_of(sensor_stream(Model::kVLP32C, 0.5, later));
  packets.insert(packets.end(), rest.begin(), rest.end());
  const Outcome run = run_pcap(write_pcap(packets, "silent"), {"sensors[0].source.rate=1"});
  ASSERT_TRUE(run.saw(HealthState::kSilent)) << run.reasons();
  EXPECT_NE(run.reasons().find("no packets on port 2368 for"), std::string::npos);
  // The rotation in progress when the packets stopped was delivered during the silence, not
  // held until the next packet: a status in the silence counts it.
  const auto silent = std::find_if(run.statuses.begin(), run.statuses.end(), [](const auto& s) {
    return s.health.state == HealthState::kSilent;
  });
  ASSERT_NE(silent, run.statuses.end());
  EXPECT_EQ(silent->rotations_published, 6u);  // 10 -> 180 deg, four turns, the rest
  EXPECT_TRUE(run.saw(HealthState::kHealthy)) << run.reasons();
}

TEST(Counters, DropsWhenDetectionFallsBehindAddUpAndAreReported) {
  // A live-like replay (no waiting for the detector) at the sensor's pace, detection made slower
  // than the sensor (150 ms a rotation, two workers, 10 rotations a second).
  const Outcome run = run_pcap(write_pcap(packets_of(sensor_stream(Model::kVLP32C, 2.0)), "behind"),
                               {"sensors[0].source.rate=1", "pipeline.lossless_replay=false",
                                "pipeline.queue_depth=1", "pipeline.publish_queue=1"},
                               [](const Scan&) { std::this_thread::sleep_for(300ms); });
  const SensorStatus& s = run.last();
  EXPECT_GT(s.rotations_behind, 0u);
  EXPECT_EQ(s.rotations_dropped, s.rotations_behind);
  EXPECT_TRUE(run.saw(HealthState::kFallingBehind)) << run.reasons();
  // Each message says how many were dropped before it was published.
  for (size_t i = 0; i < run.detections.size(); ++i) {
    EXPECT_GE(run.detections[i].dropped_rotations,
              run.detections[i].sequence - static_cast<int64_t>(i));
  }
}

TEST(Counters, WorkerThreadsRotationsAreDetectedAtOnceNeverMore) {
  // A replay at full speed with a detection stage that holds each rotation until every worker has
  // one (at most 5 s: a loaded machine may assemble slowly), then 20 ms more: rotations wait, so
  // every worker is busy; none more (the first stage never holds a worker waiting for the source).
  const auto packets = packets_of(sensor_stream(Model::kVLP32C, 1.0));
  for (int workers : {1, 2, 3}) {
    SCOPED_TRACE(workers);
    std::atomic<int> now{0}, most{0};
    const Outcome run = run_pcap(
        write_pcap(packets, "workers" + std::to_string(workers)), {},
        [&](const Scan&) {
          const int n = now.fetch_add(1) + 1;
          int m = most.load();
          while (n > m && !most.compare_exchange_weak(m, n)) {
          }
          const auto until = std::chrono::steady_clock::now() + 5s;
          while (most.load() < workers && std::chrono::steady_clock::now() < until) {
            std::this_thread::sleep_for(1ms);
          }
          std::this_thread::sleep_for(20ms);
          now.fetch_sub(1);
        },
        20ms, workers);
    EXPECT_EQ(most.load(), workers);
    EXPECT_EQ(run.last().rotations_published, 11u);
  }
}

uint16_t free_udp_port() {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  socklen_t len = sizeof(addr);
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

TEST(Counters, ALiveSourceWithoutPacketsIsWaitingThenSilentAndTheWatchdogSaysSo) {
  // A UDP source on 127.0.0.1 that nobody sends to (nothing leaves this process).
  for (bool while_silent : {false, true}) {
    SCOPED_TRACE(while_silent ? "watchdog.while_silent" : "default");
    const uint16_t data = free_udp_port(), position = free_udp_port();
    const DaemonOptions options = parse_config(
        "", {"sensors[0].source.bind_address=127.0.0.1",
             "sensors[0].source.data_port=" + std::to_string(data),
             "sensors[0].source.position_port=" + std::to_string(position), "lcm.url=memq://",
             "health.startup_grace_s=0.4", "watchdog.stall_timeout_s=0.2",
             std::string("watchdog.while_silent=") + (while_silent ? "true" : "false")});
    LcmBus bus(options.lcm.url);
    tbb::task_arena arena(2, 0);
    SensorPipeline pipeline(options.sensors[0], options, bus, arena, 2, nullptr, nullptr);
    pipeline.start();
    std::this_thread::sleep_for(100ms);
    SensorStatus s = pipeline.status(steady_ns());
    EXPECT_EQ(s.health.state, HealthState::kWaiting) << s.health.reason;
    EXPECT_NE(s.health.reason.find("waiting for packets on port " + std::to_string(data)),
              std::string::npos)
        << s.health.reason;
    EXPECT_TRUE(s.progressing);  // within the grace: the watchdog is fed
    std::this_thread::sleep_for(500ms);
    s = pipeline.status(steady_ns());
    EXPECT_EQ(s.health.state, HealthState::kSilent) << s.health.reason;
    EXPECT_NE(s.health.reason.find("since the start"), std::string::npos) << s.health.reason;
    // Past the grace: no progress, so no pings and WatchdogSec restarts the daemon; unless the
    // configuration says a silent sensor is expected.
    EXPECT_EQ(s.progressing, while_silent);
    EXPECT_EQ(s.packets_received, 0u);
    pipeline.stop();
    pipeline.join();
    // Stopped, and the final status still says what was wrong over the run.
    EXPECT_EQ(pipeline.status(steady_ns()).health.reason,
              "stopped; no data packet on port " + std::to_string(data));
  }
}

}  // namespace
}  // namespace lidartag::daemon
