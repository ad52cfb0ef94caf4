// lidartagd as a program, where setups fail and outputs break (issue 10): problems found before
// READY=1 with one line, a second daemon on a sensor's port, a multicast route removed while
// publishing (in a network namespace), an LCM log and a --record file on a full filesystem (a
// small tmpfs in a mount namespace), --print-detections into a pipe whose reader goes away,
// SIGUSR1/SIGUSR2, and configuration files that are not files or too large.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <regex>
#include <thread>

#include "daemon/demo_daemon.hpp"
#include "daemon/namespaces.hpp"
#include "daemon/process.hpp"
#include "fake_notify_socket.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
// The daemon, the demo and the process runner (demo_daemon.hpp, process.hpp).
using namespace test;

#define REQUIRE_DEMO()                                                                    \
  if (!std::filesystem::exists(kDemo)) {                                                  \
    GTEST_SKIP() << "no " << kDemo << ": make it with lidartag sim pcaps/demo.yaml (see " \
                 << "pcaps/demo.yaml)";                                                   \
  }

std::string temp(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartagd_setup");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

struct FakeNotifySocket : lidartag::testing::FakeNotifySocket {
  FakeNotifySocket() : lidartag::testing::FakeNotifySocket(temp("notify.sock")) {}
};

size_t packets_in(const std::string& path) {
  driver::PcapSource source(path);
  driver::RawPacket packet;
  size_t n = 0;
  while (source.next(packet, 10ms) == driver::ReadStatus::kPacket) ++n;
  return n;
}

// The number in `text` after `prefix` (the first occurrence), or -1.
long long number_after(const std::string& text, const std::string& prefix) {
  const size_t at = text.find(prefix);
  if (at == std::string::npos) return -1;
  return std::atoll(text.c_str() + at + prefix.size());
}

// Waits until the process's standard error holds `text` (the daemon logs "running: ..." once set
// up). Used instead of a fake NOTIFY_SOCKET where the test would not keep reading it: sd_notify
// blocks once the socket's queue is full.
bool wait_for_err(const Process& p, const std::string& text, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (p.err().find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

constexpr const char* kRunning = "running: 1 sensor(s)";

// Settings for a live UDP sensor on loopback ports nobody uses.
std::vector<std::string> live_udp(uint16_t data_port, uint16_t position_port, bool share = false) {
  return {"--set", "sensors[0].source.bind_address=127.0.0.1",
          "--set", "sensors[0].source.data_port=" + std::to_string(data_port),
          "--set", "sensors[0].source.position_port=" + std::to_string(position_port),
          "--set", std::string("sensors[0].source.share_port=") + (share ? "true" : "false")};
}

// ---------------------------------------------------------------------------------------------

TEST(Setup, ProblemsStopTheDaemonBeforeReadyWithOneLine) {
  REQUIRE_DEMO();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      // The case: model auto, so the calibration used to be read on the first packet.
      {{"--set", "sensors[0].model=auto", "--set",
        "sensors[0].calibration=/nonexistent/calibration.yaml"},
       "sensors[0].calibration: calibration file '/nonexistent/calibration.yaml': No such file"},
      {{"--record", "/nonexistent-lidartag/out.pcap"},
       "record_pcap: the --record file '/nonexistent-lidartag/out.pcap': its directory"},
      {{"--record", "/dev/full"}, "record_pcap: cannot write '/dev/full': No space left on device"},
      {{"--lcm-url", "udpm://10.1.2.3:7667"},
       "lcm.url: LCM URL 'udpm://10.1.2.3:7667': '10.1.2.3' is not an IPv4 multicast group"},
      {{"--lcm-url", "file:///tmp/lidartag-setup-test.lcmlog"}, "lcm.url: LCM URL"},
      {{"--set", "sensors[0].source.file=/nonexistent/replay.pcap"},
       "sensors[0].source.file: replay file '/nonexistent/replay.pcap': No such file"},
      // On the command line the same: an input that cannot be read (1), not a usage error.
      {{"--replay", "/nonexistent/replay.pcap"},
       "sensors[0].source.file: replay file '/nonexistent/replay.pcap': No such file"},
  };
  for (const auto& [extra, message] : cases) {
    SCOPED_TRACE(extra.back());
    FakeNotifySocket sock;
    std::vector<std::string> args = {kDaemon, "--config", kDemoConfig, "--max-speed"};
    args.insert(args.end(), extra.begin(), extra.end());
    // The demo by its absolute path (the config's is relative to the source tree), unless the
    // case names another file.
    if (std::none_of(extra.begin(), extra.end(), [](const std::string& a) {
          return a.find("source.file=") != a.npos || a == "--replay";
        })) {
      args.insert(args.end(), {"--replay", kDemo});
    }
    if (std::find(args.begin(), args.end(), "--lcm-url") == args.end()) {
      args.insert(args.end(), {"--lcm-url", "memq://"});
    }
    Process p(args, {sock.env()}, temp("setup_error"));
    EXPECT_EQ(p.wait(30s), 1);
    const auto lines = lines_of(p.err());
    ASSERT_EQ(lines.size(), 1u) << p.err();
    EXPECT_EQ(lines[0].rfind("lidartagd: error: " + message, 0), 0u) << lines[0];
    EXPECT_EQ(sock.receive(100ms), "");  // never READY=1
  }
}

TEST(Setup, ASecondDaemonOnTheSameUnicastPortFailsAtStartup) {
  const auto daemon_on = [](uint16_t data, bool share) {
    std::vector<std::string> args = {kDaemon, "--lcm-url", "memq://"};
    for (const auto& a : live_udp(data, free_udp_port(), share)) args.push_back(a);
    return args;
  };
  const uint16_t data = free_udp_port();
  Process first(daemon_on(data, false), {}, temp("first"));
  ASSERT_TRUE(wait_for_err(first, kRunning, 30s)) << first.err();

  Process second(daemon_on(data, false), {}, temp("second"));
  EXPECT_EQ(second.wait(30s), 1);
  const auto lines = lines_of(second.err());
  ASSERT_EQ(lines.size(), 1u) << second.err();
  EXPECT_EQ(lines[0],
            "lidartagd: error: sensors[0].source.data_port: UDP 127.0.0.1:" + std::to_string(data) +
                " is in use by another program (a second lidartagd, or a sensor "
                "driver): stop it, give this sensor another port, or set share_port: "
                "true here and share it there too (broadcast/multicast traffic only)");
  first.signal(SIGTERM);
  EXPECT_EQ(first.wait(30s), 0) << first.err();

  // Both sharing the port (e.g. two broadcasting sensors told apart by sensor_address): both run.
  const uint16_t shared = free_udp_port();
  Process a(daemon_on(shared, true), {}, temp("share_a"));
  ASSERT_TRUE(wait_for_err(a, kRunning, 30s)) << a.err();
  Process b(daemon_on(shared, true), {}, temp("share_b"));
  ASSERT_TRUE(wait_for_err(b, kRunning, 30s)) << b.err();
  a.signal(SIGTERM);
  b.signal(SIGTERM);
  EXPECT_EQ(a.wait(30s), 0);
  EXPECT_EQ(b.wait(30s), 0);
}

TEST(Setup, NoMulticastRouteIsASetupErrorSayingHowToAddOne) {
  REQUIRE_DEMO();
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"}, "ip link set lo up",
                            temp("netns_no_route"));
  Process p({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url", ""},
            {}, temp("no_route"));
  EXPECT_EQ(p.wait(30s), 1);
  const auto lines = lines_of(p.err());
  ASSERT_EQ(lines.size(), 1u) << p.err();  // LCM's own page of advice never comes
  EXPECT_EQ(lines[0].rfind("lidartagd: error: lcm.url: LCM URL 'udpm://239.255.76.67:7667?ttl=0': "
                           "no route to the multicast group 239.255.76.67 (Network is "
                           "unreachable): add one, e.g. 'sudo ip route add 224.0.0.0/4 dev lo'",
                           0),
            0u)
      << lines[0];
}

// ---------------------------------------------------------------------------------------------

// The case: the multicast route removed while publishing. Every message lcm-logger did
// not get is counted, logged, and makes the exit status 3.
TEST(PublishFailures, RouteRemovedWhilePublishingIsCountedAndTheExitStatusIsThree) {
  REQUIRE_DEMO();
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"},
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo",
                            temp("netns_route"));
  const std::string logged = temp("route.lcmlog");
  Process logger({"/usr/bin/lcm-logger", "-f", "--flush-interval=50", logged}, {}, temp("logger"));
  std::this_thread::sleep_for(300ms);  // lcm-logger subscribed
  Process daemon({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--rate", "1", "--loop",
                  "--lcm-url", "", "--set", "status.period_s=0.1"},
                 {}, temp("route_daemon"));
  ASSERT_TRUE(wait_for_err(daemon, kRunning, 30s)) << daemon.err();
  std::this_thread::sleep_for(700ms);
  ASSERT_EQ(std::system("ip route del 224.0.0.0/4 dev lo"), 0);
  std::this_thread::sleep_for(1500ms);
  ASSERT_EQ(std::system("ip route add 224.0.0.0/4 dev lo"), 0);
  std::this_thread::sleep_for(700ms);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(60s), 3) << daemon.err();
  std::this_thread::sleep_for(300ms);
  logger.signal(SIGINT);
  EXPECT_EQ(logger.wait(10s), 0) << logger.err();

  const std::string err = daemon.err();
  EXPECT_NE(err.find("LCM: 1 message not delivered (1 in all); last: "), std::string::npos) << err;
  EXPECT_NE(err.find("Network is unreachable"), std::string::npos);
  const long long failed = number_after(err, "lidartagd error: LCM: ");
  const long long total =
      number_after(err, "lidartagd error: LCM: " + std::to_string(failed) + " of ");
  ASSERT_GT(failed, 10);  // ~10 detections and ~15 status messages a second, for 1.5 s
  ASSERT_GT(total, failed);
  size_t events = 0;
  lcm::LogFile log(logged, "r");
  ASSERT_TRUE(log.good());
  while (log.readNextEvent() != nullptr) ++events;
  // lcm-logger got exactly the messages the daemon counts as delivered.
  EXPECT_EQ(static_cast<long long>(events), total - failed) << err;
}

// ---------------------------------------------------------------------------------------------

// Runs the current test again in a mount namespace with a tmpfs of `size` on a directory whose
// path the re-run finds in $LIDARTAG_TMPFS.
#define RUN_WITH_SMALL_TMPFS(size, name)                                                   \
  const std::string tmpfs_dir = temp(name);                                                \
  std::filesystem::create_directories(tmpfs_dir);                                          \
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-m"},                                \
                            "mount -t tmpfs -o size=" size " lidartag-test " + tmpfs_dir + \
                                " && export LIDARTAG_TMPFS=" + tmpfs_dir,                  \
                            temp(std::string(name) + ".ns"));                              \
  const std::string tmpfs = std::getenv("LIDARTAG_TMPFS");

TEST(FullDisk, LcmLogStopsAtTheFullFilesystemCountsEveryLostMessageAndExitsThree) {
  REQUIRE_DEMO();
  RUN_WITH_SMALL_TMPFS("512k", "tmpfs_log");
  const std::string path = tmpfs + "/full.lcmlog";
  Process daemon({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url",
                  "file://" + path + "?mode=w", "--set", "lcm.publish_raw=true"},
                 {}, temp("full_log"));
  EXPECT_EQ(daemon.wait(120s), 3) << daemon.err();
  const std::string err = daemon.err();
  EXPECT_NE(err.find("LCM: 1 message not delivered (1 in all); last: LIDARTAG_RAW: cannot write "
                     "the LCM log '" +
                     path + "': No space left on device"),
            std::string::npos)
      << err;
  const long long failed = number_after(err, "lidartagd error: LCM: ");
  ASSERT_GT(failed, 0) << err;
  const long long total =
      number_after(err, "lidartagd error: LCM: " + std::to_string(failed) + " of ");
  ASSERT_GT(total, failed);
  // The log holds the delivered messages, whole, and nothing else.
  size_t events = 0;
  lcm::LogFile log(path, "r");
  ASSERT_TRUE(log.good());
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    ++events;
    if (e->channel == "LIDARTAG_RAW") {
      raw_packet_t p;
      EXPECT_EQ(p.decode(e->data, 0, e->datalen), e->datalen);
    }
  }
  EXPECT_GT(events, 100u);
  EXPECT_EQ(static_cast<long long>(events), total - failed);
}

TEST(FullDisk, RecordStopsWithOneErrorAndSaysWhatTheFileHolds) {
  REQUIRE_DEMO();
  RUN_WITH_SMALL_TMPFS("256k", "tmpfs_record");
  const std::string path = tmpfs + "/full.pcap";
  Process daemon({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url",
                  "memq://", "--record", path},
                 {}, temp("full_record"));
  EXPECT_EQ(daemon.wait(120s), 3) << daemon.err();
  const std::string err = daemon.err();
  const size_t demo_packets = packets_in(kDemo);
  const size_t recorded = packets_in(path);
  EXPECT_GT(recorded, 50u);
  EXPECT_LT(recorded, demo_packets);
  const std::string holds = "; the file holds the first " + std::to_string(recorded) + " packets";
  // Once when it happened, once at the end with the count of what is missing; never "recorded".
  EXPECT_NE(err.find("recording " + path + " stopped: cannot write '" + path +
                     "': No space left on device" + holds),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("recording " + path + " failed: cannot write '" + path +
                     "': No space left on device" + holds + ", " +
                     std::to_string(demo_packets - recorded) + " received later are not in it"),
            std::string::npos)
      << err;
  EXPECT_EQ(err.find("recorded "), std::string::npos) << err;
}

// ---------------------------------------------------------------------------------------------

TEST(Signals, PrintDetectionsIntoAPipeWhoseReaderGoesAwayEndsCleanly) {
  REQUIRE_DEMO();
  // What a user types: the daemon's exit status is the pipeline's first.
  Process p({"/usr/bin/bash", "-c", "\"$0\" \"$@\" | head -1; exit \"${PIPESTATUS[0]}\"", kDaemon,
             "--config", kDemoConfig, "--replay", kDemo, "--loop", "--lcm-url", "memq://",
             "--print-detections"},
            {}, temp("head"));
  EXPECT_EQ(p.wait(60s), 0) << p.err();  // not 141 (killed by SIGPIPE)
  EXPECT_EQ(lines_of(p.out()), std::vector<std::string>{"demo rotation 0: 0 tags"});
  const std::string err = p.err();
  EXPECT_NE(err.find("--print-detections: standard output was closed"), std::string::npos) << err;
  EXPECT_NE(err.find("SIGPIPE (standard output closed): stopping"), std::string::npos) << err;
  EXPECT_NE(err.find("final status: demo: vlp32c"), std::string::npos) << err;
}

TEST(Signals, Usr1LogsTheStatusNowAndUsr2IsIgnored) {
  std::vector<std::string> args = {kDaemon, "--lcm-url", "memq://"};
  for (const auto& a : live_udp(free_udp_port(), free_udp_port())) args.push_back(a);
  Process daemon(args, {}, temp("usr"));
  ASSERT_TRUE(wait_for_err(daemon, kRunning, 30s)) << daemon.err();
  daemon.signal(SIGUSR1);
  daemon.signal(SIGUSR2);
  bool usr1 = false, usr2 = false;
  for (int i = 0; i < 200 && !(usr1 && usr2); ++i) {
    std::this_thread::sleep_for(20ms);
    const std::string err = daemon.err();
    usr1 = err.find("SIGUSR1: status: lidar: (model unknown) 0 rotations published") !=
           std::string::npos;
    usr2 = err.find("SIGUSR2: ignored") != std::string::npos;
  }
  EXPECT_TRUE(usr1) << daemon.err();
  EXPECT_TRUE(usr2) << daemon.err();
  daemon.signal(SIGTERM);  // still running: stops as usual
  EXPECT_EQ(daemon.wait(30s), 0) << daemon.err();
  EXPECT_NE(daemon.err().find("final status: lidar"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------

TEST(CommandLine, ConfigurationsThatAreNotFilesOrTooLargeAreOneShortLineAndExitTwo) {
  const std::string dir = temp("config_dir");
  std::filesystem::create_directories(dir);
  const std::string big = temp("big.yaml");
  std::ofstream(big) << std::string(2 * 1024 * 1024, '#');
  const std::string duplicate = temp("duplicate.yaml");
  std::ofstream(duplicate) << "lcm:\n  url: memq://\n  url: udpm://\n";
  const std::string long_value = temp("long_value.yaml");
  std::ofstream(long_value) << "status:\n  period_s: " << std::string(900'000, '9') << "\n";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--config", "/dev/zero"}, "config: '/dev/zero': not a regular file (a character device)"},
      {{"--config", dir}, "config: '" + dir + "': not a regular file (a directory)"},
      {{"--config", big},
       "config: '" + big + "': 2097152 bytes: larger than the limit of 1048576 bytes (1 MiB)"},
      {{"--config", duplicate},
       "lcm.url: duplicate key (lines 2 and 3 of config " + duplicate + ")"},
      {{"--config", long_value},
       "status.period_s: '" + std::string(80, '9') + "... (900000 bytes)': expected a number"},
      {{"--set", "logging.level=" + std::string(100'000, 'x')},
       "logging.level: '" + std::string(80, 'x') + "... (100000 bytes)': expected trace"},
  };
  for (const auto& [args, message] : cases) {
    std::vector<std::string> argv = {kDaemon};
    argv.insert(argv.end(), args.begin(), args.end());
    SCOPED_TRACE(args.front());
    Process p(argv, {}, temp("bad_config"));
    EXPECT_EQ(p.wait(30s), 2);
    const auto lines = lines_of(p.err());
    ASSERT_EQ(lines.size(), 1u) << p.err().substr(0, 1000);
    EXPECT_LT(lines[0].size(), 400u);
    EXPECT_EQ(lines[0].rfind("lidartagd: config error: " + message, 0), 0u) << lines[0];
  }
}

}  // namespace
}  // namespace lidartag::daemon
