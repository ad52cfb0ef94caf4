// lidartagd without privileges: the replay and the UDP/multicast paths as user nobody (no
// capabilities at all), and live interface capture with CAP_NET_RAW as its one capability (what
// config/lidartagd-capture.conf gives the systemd unit). The user switch needs root (skipped with
// a message otherwise); the network tests run inside their own network namespace, entered as root
// (`unshare -n`), the daemon then started as nobody inside it with setpriv.
#include <arpa/inet.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <filesystem>
#include <lcm/lcm-cpp.hpp>

#include "daemon/demo_daemon.hpp"
#include "daemon/namespaces.hpp"
#include "daemon/process.hpp"
#include "fake_notify_socket.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "lidartag/status_t.hpp"
#include "lidartag/tag_detections_t.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
// The daemon, the demo and the process runner (demo_daemon.hpp, process.hpp).
using namespace test;

// A directory every user may write (the daemon's outputs as nobody), one per test process.
std::string temp(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartagd_priv");
  const std::string& dir = scratch_dir.path();
  std::filesystem::permissions(dir, std::filesystem::perms::all);
  return dir + "/" + name;
}

// setpriv to nobody: no groups, no capabilities in any set (bounding set emptied), except `caps`
// ("net_raw") given as inheritable and ambient so that the daemon keeps exactly those.
std::vector<std::string> as_nobody(const std::string& caps = "") {
  const std::string keep = caps.empty() ? "-all" : "-all,+" + caps;
  return {"/usr/bin/setpriv",       "--reuid=nobody",     "--regid=nogroup",
          "--clear-groups",         "--inh-caps=" + keep, "--ambient-caps=" + keep,
          "--bounding-set=" + keep, "--no-new-privs",     "--"};
}

#define REQUIRE_ROOT_AND_DEMO()                                                               \
  if (geteuid() != 0) GTEST_SKIP() << "not root: cannot switch to user nobody (run as root)"; \
  if (!std::filesystem::exists(kDemo)) GTEST_SKIP() << "no " << kDemo;                        \
  if (!std::filesystem::exists("/usr/bin/setpriv")) GTEST_SKIP() << "no setpriv (util-linux)"

uid_t nobody_uid() {
  const passwd* p = getpwnam("nobody");
  return p != nullptr ? p->pw_uid : 65534;
}

std::vector<std::string> with(std::vector<std::string> prefix, const std::vector<std::string>& a) {
  prefix.insert(prefix.end(), a.begin(), a.end());
  return prefix;
}

// The demo replayed as root: the reference lines.
std::vector<std::string> root_replay_lines() {
  Process p({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url",
             "memq://", "--print-detections"},
            {}, temp("root_replay"));
  EXPECT_EQ(p.wait(120s), 0) << p.err();
  return lines_of(p.out());
}

std::vector<lidartag::status_t> statuses(const std::string& log, uint64_t* detections = nullptr) {
  std::vector<lidartag::status_t> out;
  lcm::LogFile in(log, "r");
  EXPECT_TRUE(in.good()) << log;
  if (!in.good()) return out;
  while (const lcm::LogEvent* e = in.readNextEvent()) {
    try {
      if (e->channel == "LIDARTAG_STATUS") {
        if (out.emplace_back().decode(e->data, 0, e->datalen) != e->datalen) out.pop_back();
      } else if (e->channel == "LIDARTAG_DETECTIONS" && detections != nullptr) {
        lidartag::tag_detections_t d;
        if (d.decode(e->data, 0, e->datalen) == e->datalen && d.ndetections > 0) ++*detections;
      }
    } catch (const std::exception&) {
      ADD_FAILURE() << "undecodable " << e->channel;
    }
  }
  return out;
}

TEST(Unprivileged, ReplayAsNobodyGivesTheRootReplay) {
  REQUIRE_ROOT_AND_DEMO();
  const std::string log = temp("nobody_replay.lcmlog");
  std::filesystem::remove(log);
  Process p(with(as_nobody(), {kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed",
                               "--lcm-url", "file://" + log + "?mode=w", "--print-detections"}),
            {}, temp("nobody_replay"));
  ASSERT_EQ(p.wait(120s), 0) << p.err();
  EXPECT_EQ(lines_of(p.out()), root_replay_lines());
  // The log was written by nobody (the switch happened), and its last status says all published.
  struct stat st {};
  ASSERT_EQ(stat(log.c_str(), &st), 0);
  EXPECT_EQ(st.st_uid, nobody_uid());
  const auto s = statuses(log);
  ASSERT_FALSE(s.empty());
  EXPECT_GT(s.back().rotations_published, 0);
  EXPECT_EQ(s.back().rotations_published, s.back().rotations_assembled);
}

// ---------------------------------------------------------------------------------------------

struct NotifySocket : lidartag::testing::FakeNotifySocket {
  NotifySocket() : lidartag::testing::FakeNotifySocket(temp("notify.sock")) {
    chmod(path().c_str(), 0666);  // the daemon writes to it as nobody
  }
};

// The daemon as nobody (plus `caps`) on a live source: READY, the demo sent, SIGTERM; its printed
// detections must be the root replay's.
void expect_live_as_nobody_equals_replay(const std::vector<std::string>& settings,
                                         const std::string& caps, const std::string& lcm_url) {
  NotifySocket sock;
  std::vector<std::string> args = {kDaemon,     "--config", kDemoConfig,
                                   "--lcm-url", lcm_url,    "--print-detections"};
  for (const auto& s : settings) args.insert(args.end(), {"--set", s});
  Process daemon(with(as_nobody(caps), args), {sock.env()}, temp("live_nobody"));
  ASSERT_EQ(sock.receive(30s).rfind("READY=1", 0), 0u) << daemon.err();
  EXPECT_GT(send_demo(23068, 28308), 1000u);
  std::this_thread::sleep_for(1s);  // the last rotations through the detector
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(30s), 0) << daemon.err();
  EXPECT_EQ(lines_of(daemon.out()), root_replay_lines());
}

TEST(Unprivileged, UdpAndLcmMulticastAsNobody) {
  REQUIRE_ROOT_AND_DEMO();
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"},
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo",
                            temp("netns_udp"));
  // lcm-logger (root) records what the daemon (nobody) publishes on LCM's default multicast URL.
  const std::string logged = temp("nobody_multicast.lcmlog");
  Process logger({"/usr/bin/lcm-logger", "-f", "--flush-interval=50", logged}, {}, temp("logger"));
  std::this_thread::sleep_for(300ms);
  expect_live_as_nobody_equals_replay(
      {"sensors[0].source.kind=udp", "sensors[0].source.bind_address=127.0.0.1",
       "sensors[0].source.data_port=23068", "sensors[0].source.position_port=28308"},
      "", "");
  std::this_thread::sleep_for(300ms);
  logger.signal(SIGINT);
  EXPECT_EQ(logger.wait(10s), 0) << logger.err();
  uint64_t with_tags = 0;
  const auto s = statuses(logged, &with_tags);
  ASSERT_FALSE(s.empty());
  EXPECT_GT(s.back().packets_received, 1000);
  EXPECT_GT(with_tags, 5u);
}

// Interface capture: refused without CAP_NET_RAW with a line that names it (exit status 1, before
// READY), and with CAP_NET_RAW alone it captures the demo on lo like the replay.
TEST(Capture, InterfaceCaptureNeedsCapNetRawAndNothingElse) {
  REQUIRE_ROOT_AND_DEMO();
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"},
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo",
                            temp("netns_capture"));
  const std::vector<std::string> capture = {
      "sensors[0].source.kind=interface", "sensors[0].source.interface=lo",
      "sensors[0].source.data_port=23068", "sensors[0].source.position_port=28308"};
  {
    std::vector<std::string> args = {kDaemon, "--config", kDemoConfig, "--lcm-url", "memq://"};
    for (const auto& s : capture) args.insert(args.end(), {"--set", s});
    NotifySocket sock;
    Process refused(with(as_nobody(), args), {sock.env()}, temp("no_cap"));
    EXPECT_EQ(refused.wait(30s), 1) << refused.err();
    EXPECT_EQ(sock.receive(100ms), "");  // never READY
    const auto lines = lines_of(refused.err());
    ASSERT_EQ(lines.size(), 1u) << refused.err();
    EXPECT_EQ(lines[0].rfind("lidartagd: error: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find("'lo'"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("CAP_NET_RAW"), std::string::npos) << lines[0];
  }
  expect_live_as_nobody_equals_replay(capture, "net_raw", "memq://");
}

}  // namespace
}  // namespace lidartag::daemon
