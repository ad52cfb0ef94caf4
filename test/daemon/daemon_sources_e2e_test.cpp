// lidartagd's sources through the vendor seam (driver/sources): replay of simulated Ouster captures
// (the metadata found beside the pcap, or named by the configuration), Ouster metadata that
// contradicts the packets, Ouster live UDP inside a network namespace (lidar port 7502, IMU port
// 7503 counted apart), ROS bags against the pcaps of the same packets (../shared/captures/bags,
// skipped when absent), and the configuration's errors for Ouster sensors.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>
#include <tuple>

#include "daemon/lcm_log_messages.hpp"
#include "daemon/namespaces.hpp"
#include "daemon/process.hpp"
#include "fake_notify_socket.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/point_cloud_t.hpp"
#include "lidartag/status_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
using namespace test;
using lidartag::testing::FakeNotifySocket;

const std::string kDaemon = LIDARTAGD_PATH;
const std::string kCli = LIDARTAG_CLI_PATH;
const std::string kBags = LIDARTAG_SHARED_DIR "/captures/bags";
const std::string kCaptures = LIDARTAG_SHARED_DIR "/captures";

std::string temp(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartagd_sources");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

// A simulated Ouster capture: NAME.pcap, NAME.json (its metadata) and NAME.truth.json; a 1.2 m
// tag16h5 (id 3) 5 m ahead, as test/sim/ouster_scene.yaml. Returns NAME.pcap.
std::string simulate(const std::string& name, const std::string& model, const std::string& profile,
                     int rotations, const std::string& mode = "1024x10") {
  const std::string stem = temp(name);
  if (std::filesystem::exists(stem + ".pcap")) return stem + ".pcap";
  std::ofstream(stem + ".yaml") << "sensor: {model: " << model << ", lidar_mode: " << mode
                                << ", profile: " << profile
                                << ", height: 1.0}\n"
                                   "tags:\n"
                                   "  - {family: tag16h5, id: 3, size: 1.2, center: [5.0, 0.0, "
                                   "1.0], rotation: 45}\n"
                                   "rotations: "
                                << rotations << "\n";
  Process sim(
      {kCli, "sim", stem + ".yaml", "--out", stem + ".pcap", "--truth", stem + ".truth.json"}, {},
      stem + ".sim");
  EXPECT_EQ(sim.wait(300s), 0) << sim.err();
  return stem + ".pcap";
}

// Appends the records of the classic pcap `from` to `out` (the global header too when `header`),
// leaving out every `skip`-th record (0: none). Returns the records read.
size_t copy_records(const std::string& from, std::ofstream& out, bool header, size_t skip) {
  std::ifstream raw(from, std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(raw)),
                                std::istreambuf_iterator<char>());
  if (bytes.size() < 24) return 0;
  if (header) out.write(bytes.data(), 24);
  size_t at = 24, n = 0;
  while (at + 16 <= bytes.size()) {
    uint32_t incl = 0;
    std::memcpy(&incl, bytes.data() + at + 8, 4);
    const size_t len = 16 + incl;
    if (at + len > bytes.size()) break;
    if (skip == 0 || ++n % skip != 0)
      out.write(bytes.data() + at, static_cast<std::streamsize>(len));
    if (skip == 0) ++n;
    at += len;
  }
  return n;
}

// The daemon's configuration for one sensor `extra` (YAML mapping entries of the sensor) detecting
// the simulated tag.
std::string config(const std::string& name, const std::string& extra) {
  const std::string path = temp(name + ".yaml");
  std::ofstream(path) << "sensors:\n  - name: os\n    frame_id: os_sensor\n"
                      << extra << "detector:\n  tag_sizes_m: [1.2]\n  families: [tag16h5]\n";
  return path;
}

using lidartag::daemon::lcm_test::decode;
using Decoded = lidartag::daemon::lcm_test::LoggedMessages;
using lidartag::daemon::lcm_test::read_log;

// Runs the daemon to the end of its replay into an LCM log; returns its exit status.
int replay(const std::string& log, const std::vector<std::string>& args,
           std::string* err = nullptr) {
  std::vector<std::string> all = {kDaemon, "--max-speed", "--lcm-url", "file://" + log + "?mode=w"};
  all.insert(all.end(), args.begin(), args.end());
  std::filesystem::remove(log);
  Process p(all, {}, log + ".run");
  const int status = p.wait(300s);
  if (err != nullptr) *err = p.err();
  return status;
}

// The tag's truth position (sensor frame) of the simulated capture `pcap`.
std::array<double, 3> truth_position(const std::string& pcap) {
  std::ifstream in(pcap.substr(0, pcap.size() - 5) + ".truth.json");
  const auto j = nlohmann::json::parse(in);
  return j.at("rotations").at(0).at("tags").at(0).at("position").get<std::array<double, 3>>();
}

// What every Ouster replay status must say: the counters add up, nothing lost or refused.
void expect_clean_ouster_status(const lidartag::status_t& last, const std::string& model,
                                const std::string& profile) {
  EXPECT_EQ(last.model, model);
  EXPECT_EQ(last.return_mode, profile);
  EXPECT_GT(last.packets_data, 0);
  EXPECT_EQ(last.packets_decoded, last.packets_data);
  EXPECT_EQ(last.packets_received, last.packets_data + last.position_packets);
  EXPECT_EQ(last.packets_malformed, 0);
  EXPECT_EQ(last.packets_model_mismatch, 0);
  EXPECT_EQ(last.packets_missing, 0);
  EXPECT_EQ(last.rotations_dropped, 0);
  EXPECT_EQ(last.rotations_published, last.rotations_assembled);
  EXPECT_EQ(last.state, int8_t{lidartag::status_t::STATE_ENDED}) << last.reason;
  EXPECT_EQ(last.reason, "the source ended");
}

// Every complete rotation holds the tag where the truth has it.
void expect_tag_in_every_complete_rotation(const Decoded& d, const std::array<double, 3>& truth,
                                           size_t min_complete) {
  size_t complete = 0;
  for (const auto& r : d.detections) {
    if (!r.complete) continue;
    ++complete;
    ASSERT_EQ(r.ndetections, 1) << "rotation " << r.sequence;
    const auto& t = r.detections[0];
    EXPECT_EQ(t.family, "tag16h5");
    EXPECT_EQ(t.id, 3);
    EXPECT_LT(
        std::hypot(t.position[0] - truth[0], t.position[1] - truth[1], t.position[2] - truth[2]),
        0.15)
        << "rotation " << r.sequence;
  }
  EXPECT_GE(complete, min_complete);
}

// ---------------------------------------------------------------------------------------------

TEST(OusterReplay, SimulatedOs1_64FoundBesideItsMetadataPublishesTheTag) {
  const std::string pcap = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  const std::string log = temp("os1_64.lcmlog");
  std::string err;
  ASSERT_EQ(replay(log, {"--config", config("os64", ""), "--replay", pcap}, &err), 0) << err;
  EXPECT_NE(err.find("Ouster"), std::string::npos) << err;
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty());
  const auto& last = d.status.back();
  expect_clean_ouster_status(last, "os1-64", "RNG19_RFL8_SIG16_NIR16");
  EXPECT_EQ(last.position_packets, 0);  // the simulator writes no IMU packets
  EXPECT_EQ(static_cast<int64_t>(d.detections.size()), last.rotations_published);
  expect_tag_in_every_complete_rotation(d, truth_position(pcap), 3);
}

TEST(OusterReplay, ConfiguredMetadataAndModelOfAnOs1_128Legacy) {
  const std::string pcap = simulate("os1_128_legacy", "os1-128", "legacy", 3);
  const std::string metadata = pcap.substr(0, pcap.size() - 5) + ".json";
  const std::string log = temp("os1_128.lcmlog");
  const std::string cfg = config("os128", "    model: os1-128\n    metadata: " + metadata +
                                              "\n    source: {kind: pcap, file: " + pcap + "}\n");
  std::string err;
  ASSERT_EQ(replay(log, {"--config", cfg}, &err), 0) << err;
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty());
  expect_clean_ouster_status(d.status.back(), "os1-128", "LEGACY");
  expect_tag_in_every_complete_rotation(d, truth_position(pcap), 2);
}

// The metadata of another sensor (an OS1-128's for an OS1-64's packets): every packet refused as a
// contradiction, counted and named in the health, nothing decoded, no rotation.
TEST(OusterHealth, MetadataThatContradictsThePacketsIsNamedAndCounted) {
  const std::string pcap64 = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  const std::string pcap128 = simulate("os1_128_legacy", "os1-128", "legacy", 3);
  const std::string wrong = pcap128.substr(0, pcap128.size() - 5) + ".json";
  const std::string log = temp("contradiction.lcmlog");
  std::string err;
  (void)replay(log, {"--config", config("wrong", ""), "--replay", pcap64, "--metadata", wrong},
               &err);
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty()) << err;
  const auto& last = d.status.back();
  EXPECT_EQ(last.model, "os1-128");  // as the metadata says
  EXPECT_GT(last.packets_data, 0);
  EXPECT_EQ(last.packets_decoded, 0);
  EXPECT_EQ(last.packets_model_mismatch, last.packets_data);
  EXPECT_EQ(last.packets_malformed, 0);
  EXPECT_EQ(last.rotations_assembled, 0);
  EXPECT_EQ(last.state, int8_t{lidartag::status_t::STATE_ENDED}) << last.reason;
  EXPECT_NE(last.reason.find("none of its"), std::string::npos) << last.reason;
  EXPECT_NE(last.reason.find("did not fit the model decoded"), std::string::npos) << last.reason;
  EXPECT_NE(last.reason.find("RNG19_RFL8_SIG16_NIR16 with 64 pixels"), std::string::npos)
      << last.reason;
}

// Frames that lose columns: every 7th lidar packet dropped from the capture; the loss is counted
// (packets_missing) and the frames marked incomplete.
TEST(OusterHealth, FramesThatLoseColumnsCountTheMissingPackets) {
  const std::string pcap = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  const std::string lossy = temp("lossy.pcap");
  {
    std::ofstream out(lossy, std::ios::binary);
    ASSERT_GT(copy_records(pcap, out, true, 7), 100u);
  }
  std::filesystem::copy_file(pcap.substr(0, pcap.size() - 5) + ".json", temp("lossy.json"),
                             std::filesystem::copy_options::overwrite_existing);
  const std::string log = temp("lossy.lcmlog");
  std::string err;
  ASSERT_EQ(replay(log, {"--config", config("lossy", ""), "--replay", lossy}, &err), 0) << err;
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty());
  const auto& last = d.status.back();
  EXPECT_EQ(last.packets_decoded, last.packets_data);
  EXPECT_GT(last.packets_missing, 0);
  EXPECT_NE(last.reason.find("of the data packets missing"), std::string::npos) << last.reason;
  for (const auto& r : d.detections) EXPECT_FALSE(r.complete) << "rotation " << r.sequence;
}

// A lidar mode change: the sensor switched from 1024x10 to 2048x10 while the metadata says
// 1024x10. The packets of measurement ids past 1024 are counted as contradicting the metadata and
// the reason says the lidar mode changed.
TEST(OusterHealth, ALidarModeChangeIsAModelMismatch) {
  const std::string pcap = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  const std::string wide = simulate("os1_64_2048", "os1-64", "rng19", 2, "2048x10");
  const std::string changed = temp("mode_change.pcap");
  {
    std::ofstream out(changed, std::ios::binary);
    ASSERT_GT(copy_records(pcap, out, true, 0), 100u);
    ASSERT_GT(copy_records(wide, out, false, 0), 100u);
  }
  const std::string log = temp("mode_change.lcmlog");
  std::string err;
  (void)replay(log,
               {"--config", config("mode", ""), "--replay", changed, "--metadata",
                pcap.substr(0, pcap.size() - 5) + ".json"},
               &err);
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty()) << err;
  const auto& last = d.status.back();
  EXPECT_GT(last.packets_model_mismatch, 0);
  EXPECT_EQ(last.packets_decoded + last.packets_model_mismatch, last.packets_data);
  EXPECT_NE(last.reason.find("another lidar mode"), std::string::npos) << last.reason;
  EXPECT_NE(last.reason.find("did not fit the model decoded"), std::string::npos) << last.reason;
  // The frames before the change were detected.
  size_t with_tag = 0;
  for (const auto& r : d.detections) with_tag += r.ndetections > 0 ? 1u : 0u;
  EXPECT_GE(with_tag, 3u);
}

TEST(OusterConfig, ModelAndMetadataErrors) {
  const std::string pcap = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  const std::string metadata = pcap.substr(0, pcap.size() - 5) + ".json";
  struct Case {
    std::string sensor;
    int status;
    std::string says;
  };
  const std::vector<Case> cases = {
      // The metadata describes an OS1-64.
      {"    model: os1-128\n    metadata: " + metadata + "\n", 1,
       "not the configured model os1-128"},
      {"    model: os1-128\n", 2, "sensors[0].metadata"},
      {"    model: vlp32c\n    metadata: " + metadata + "\n", 2, "sensors[0].model"},
      {"    model: os3-64\n", 2, "Ouster: os0, os1, os2"},
      {"    metadata: /nonexistent/os.json\n", 1, "sensors[0].metadata"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.sensor);
    Process p({kDaemon, "--config",
               config("bad", c.sensor + "    source: {kind: pcap, file: " + pcap + "}\n"),
               "--lcm-url", "memq://"},
              {}, temp("bad_run"));
    EXPECT_EQ(p.wait(60s), c.status) << p.err();
    EXPECT_NE(p.err().find(c.says), std::string::npos) << p.err();
  }
}

// Live: the simulated capture's lidar packets sent to 127.0.0.1:7502 at their pace and IMU-sized
// packets to 7503, inside a network namespace of its own (the sensor's ports are free there).
TEST(OusterLiveUdp, LidarAndImuPortsOfTheSensorInANetworkNamespace) {
  const std::string pcap = simulate("os1_64_rng19", "os1-64", "rng19", 4);
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"}, "ip link set lo up",
                            temp("netns_ouster"));
  const std::string metadata = pcap.substr(0, pcap.size() - 5) + ".json";
  const std::string log = temp("live.lcmlog");
  std::filesystem::remove(log);
  FakeNotifySocket sock(temp("notify.sock"));
  Process daemon({kDaemon, "--config",
                  config("live", "    metadata: " + metadata +
                                     "\n    source: {kind: udp, bind_address: 127.0.0.1, "
                                     "sensor_address: 127.0.0.1}\n"),
                  "--lcm-url", "file://" + log + "?mode=w"},
                 {sock.env()}, temp("live"));
  ASSERT_EQ(sock.receive(30s).rfind("READY=1", 0), 0u) << daemon.err();
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  driver::PcapSourceOptions o;
  o.data_port = 7502;
  o.position_port = 7503;
  o.pacing = driver::ReplayPacing::kCaptureTime;
  driver::PcapSource source(pcap, o);
  driver::RawPacket packet;
  size_t lidar = 0, imu = 0;
  const std::vector<uint8_t> imu_packet(48, 0x5a);
  const auto send = [&](const void* data, size_t size, uint16_t port) {
    to.sin_port = htons(port);
    return sendto(fd, data, size, 0, reinterpret_cast<sockaddr*>(&to), sizeof(to)) ==
           static_cast<ssize_t>(size);
  };
  for (;;) {
    const auto status = source.next(packet, 100ms);
    if (status == driver::ReadStatus::kTimeout) continue;
    if (status != driver::ReadStatus::kPacket) break;
    lidar += send(packet.payload.data(), packet.payload.size(), 7502) ? 1u : 0u;
    // An IMU packet every 8 lidar packets (the sensor sends them at 100 Hz).
    if (lidar % 8 == 0) imu += send(imu_packet.data(), imu_packet.size(), 7503) ? 1u : 0u;
  }
  close(fd);
  ASSERT_GT(lidar, 100u);
  std::this_thread::sleep_for(1s);  // the flush of the last frame, the detector
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(30s), 0) << daemon.err();
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty());
  const auto& last = d.status.back();
  EXPECT_EQ(last.model, "os1-64");
  EXPECT_EQ(static_cast<size_t>(last.packets_data), lidar);
  EXPECT_EQ(static_cast<size_t>(last.position_packets), imu);  // counted apart, never lidar data
  EXPECT_EQ(last.packets_decoded, last.packets_data);
  EXPECT_EQ(last.packets_malformed, 0);
  EXPECT_EQ(static_cast<size_t>(last.packets_received), lidar + imu);
  expect_tag_in_every_complete_rotation(d, truth_position(pcap), 2);

  // Nobody sending: the status names the sensor's lidar port.
  FakeNotifySocket quiet_sock(temp("quiet.sock"));
  Process quiet({kDaemon, "--config",
                 config("quiet", "    metadata: " + metadata +
                                     "\n    source: {kind: udp, bind_address: 127.0.0.1}\n"),
                 "--lcm-url", "memq://"},
                {quiet_sock.env()}, temp("quiet"));
  ASSERT_EQ(quiet_sock.receive(30s).rfind("READY=1", 0), 0u) << quiet.err();
  std::this_thread::sleep_for(1500ms);
  quiet.signal(SIGTERM);
  ASSERT_EQ(quiet.wait(30s), 0) << quiet.err();
  EXPECT_NE(quiet.err().find("no data packet on port 7502"), std::string::npos) << quiet.err();
}

// ---- ROS bags (../shared/captures/bags) --------------------------------------------------------

#define REQUIRE_BAGS()                                                                \
  if (!std::filesystem::exists(kBags)) {                                              \
    GTEST_SKIP() << "no " << kBags << " (the real bags live beside the project, see " \
                 << "docs/bags.md)";                                                  \
  }

// A ROS 2 bag of VelodyneScan messages and the pcap of the same packets: the same rotations, bit
// for bit (the decimated clouds of every column), the same counters.
TEST(BagReplay, Rosbag2EqualsThePcapOfTheSamePackets) {
  REQUIRE_BAGS();
  for (const auto& [bag, pcap] : {std::pair{"rosbag2/vlp16_dual", "vlp16_dual_nebula.pcap"},
                                  std::pair{"rosbag2/vlp32c", "vlp32c_nebula_fov.pcap"}}) {
    SCOPED_TRACE(bag);
    std::vector<Decoded> runs;
    for (const std::string& file : {kBags + "/" + bag, kCaptures + "/" + std::string(pcap)}) {
      const std::string log = temp("bag.lcmlog");
      std::string err;
      ASSERT_EQ(replay(log, {"--replay", file, "--set", "lcm.cloud_decimation=1"}, &err), 0) << err;
      runs.push_back(read_log(log));
    }
    ASSERT_FALSE(runs[0].status.empty());
    ASSERT_FALSE(runs[1].status.empty());
    const auto &a = runs[0].status.back(), &b = runs[1].status.back();
    EXPECT_EQ(a.model, b.model);
    EXPECT_EQ(a.packets_data, b.packets_data);
    EXPECT_EQ(a.packets_decoded, b.packets_decoded);
    EXPECT_EQ(a.rotations_assembled, b.rotations_assembled);
    EXPECT_GT(a.rotations_assembled, 0);
    ASSERT_EQ(runs[0].clouds.size(), runs[1].clouds.size());
    for (size_t i = 0; i < runs[0].clouds.size(); ++i) {
      const auto &x = runs[0].clouds[i], &y = runs[1].clouds[i];
      EXPECT_EQ(x.npoints, y.npoints) << i;
      EXPECT_EQ(x.utime, y.utime) << i;
      EXPECT_TRUE(x.x == y.x && x.y == y.y && x.z == y.z && x.intensity == y.intensity) << i;
    }
    ASSERT_EQ(runs[0].detections.size(), runs[1].detections.size());
    for (size_t i = 0; i < runs[0].detections.size(); ++i)
      EXPECT_EQ(runs[0].detections[i].complete, runs[1].detections[i].complete) << i;
  }
}

// The ROS 1 bag of Ouster OS0-128 packets (one whole 512-column frame, IMU packets, the metadata
// topic): decoded as the Ouster pcaps are, the IMU packets counted apart.
TEST(BagReplay, Ros1OusterPacketsWithTheMetadataTopic) {
  REQUIRE_BAGS();
  const std::string log = temp("ouster_bag.lcmlog");
  std::string err;
  ASSERT_EQ(replay(log, {"--replay", kBags + "/ros1/ouster_os0-128_512x10_packets.bag"}, &err), 0)
      << err;
  const Decoded d = read_log(log);
  ASSERT_FALSE(d.status.empty());
  const auto& last = d.status.back();
  expect_clean_ouster_status(last, "os0-128", "RNG15_RFL8_NIR8");
  EXPECT_EQ(last.packets_data, 32);
  EXPECT_EQ(last.position_packets, 10);
  ASSERT_EQ(d.detections.size(), 1u);
  EXPECT_TRUE(d.detections[0].complete);
  EXPECT_EQ(d.detections[0].ndetections, 0);  // no tag in it
}

// --start/--duration (source.start, source.duration) on a replayed pcap and a bag: only the
// packets of the window reach the pipeline, as `lidartag info` reads them (the pcap's window
// counted here from its own packets); with --loop they are refused at setup.
TEST(BagReplay, TimeWindowsOnAPcapAndABag) {
  REQUIRE_BAGS();
  const std::string pcap = kCaptures + "/vlp16_dual_nebula.pcap";
  int64_t data = 0;
  {
    driver::PcapSource source(pcap);
    driver::RawPacket p;
    int64_t first = 0;
    bool anchored = false;
    while (source.next(p, 0ms) == driver::ReadStatus::kPacket) {
      if (!anchored) first = p.receive_time_ns;
      anchored = true;
      const double t = static_cast<double>(p.receive_time_ns - first) * 1e-9;
      if (t >= 0.15 && t < 0.35 && p.destination_port == driver::kDefaultDataPort) ++data;
    }
  }
  ASSERT_GT(data, 100);
  // The pcap with the command line's options, the bag with the configuration's keys.
  const std::vector<std::string> window_flags = {"--start", "0.15", "--duration", "0.2"};
  const std::vector<std::string> window_keys = {"--set", "sensors[0].source.start=0.15", "--set",
                                                "sensors[0].source.duration=0.2"};
  for (const auto& [file, expected, window] :
       {std::tuple{pcap, data, window_flags},
        std::tuple{kBags + "/rosbag2/vlp16_dual", int64_t{301}, window_keys}}) {
    SCOPED_TRACE(file);
    const std::string log = temp("window.lcmlog");
    std::vector<std::string> args = {"--replay", file};
    args.insert(args.end(), window.begin(), window.end());
    std::string err;
    ASSERT_EQ(replay(log, args, &err), 0) << err;
    const Decoded d = read_log(log);
    ASSERT_FALSE(d.status.empty());
    EXPECT_EQ(d.status.back().packets_data, expected);
  }
  std::string err;
  EXPECT_EQ(
      replay(temp("window_loop.lcmlog"), {"--replay", pcap, "--start", "0.1", "--loop"}, &err), 1);
  EXPECT_NE(err.find("looped replay"), std::string::npos) << err;
}

// A bag whose LiDAR topic holds point clouds, not packets, and a topic that is not there: one
// clear line, exit status 1.
TEST(BagReplay, TopicErrorsAreOneLine) {
  REQUIRE_BAGS();
  const std::string bag = kBags + "/ros1/luminar_pointcloud2_lz4.bag";
  for (const auto& [args, says] :
       {std::pair{std::vector<std::string>{"--replay", bag}, std::string("holds point clouds")},
        std::pair{std::vector<std::string>{"--replay", bag, "--topic", "/nope"},
                  std::string("no topic /nope; its topics: ")}}) {
    std::string err;
    EXPECT_EQ(replay(temp("topic.lcmlog"), args, &err), 1) << err;
    EXPECT_NE(err.find(says), std::string::npos) << err;
  }
}

}  // namespace
}  // namespace lidartag::daemon
