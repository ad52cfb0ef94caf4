// The systemd watchdog in process: a Daemon replaying the demo at a quarter of the recorded pace, a
// fake NOTIFY_SOCKET, and a detection stage stalled on purpose (the pipeline's test seam).
// WATCHDOG=1 stops while no rotation gets published and comes back when the pipeline moves again;
// STATUS= says which sensor stalled and why.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "fake_notify_socket.hpp"
#include "lidartag/daemon/daemon.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

const std::string kDemoConfig = LIDARTAG_SOURCE_DIR "/config/demo.yaml";
const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";

struct Message {
  std::string text;
  Clock::time_point when;
};

TEST(Watchdog, NoPingsWhileThePipelineIsStalledAndPingsAgainAfter) {
  if (!std::filesystem::exists(kDemo)) GTEST_SKIP() << "no " << kDemo;
  const std::string path =
      ::testing::TempDir() + "/lidartag_watchdog_" + std::to_string(::getpid()) + ".sock";
  testing::FakeNotifySocket socket(path);
  ASSERT_EQ(setenv("NOTIFY_SOCKET", path.c_str(), 1), 0);
  ASSERT_EQ(setenv("WATCHDOG_USEC", "200000", 1), 0);  // pings every 100 ms while progressing

  DaemonOptions options = load_config(
      kDemoConfig, {"sensors[0].source.file=" + kDemo, "sensors[0].source.rate=0.25",
                    "lcm.url=memq://", "status.period_s=0.1", "watchdog.stall_timeout_s=0.3"});
  std::atomic<bool> release{false};
  std::atomic<int64_t> stalled_at{0};
  RunOptions run;
  run.detect_hook = [&](const Scan& scan) {
    if (scan.sequence != 3) return;
    stalled_at.store(Clock::now().time_since_epoch().count());
    release.wait(false);  // the detector hangs until the test lets it go
  };
  int status = -1;
  std::vector<Message> messages;
  {
    Daemon daemon(std::move(options), run, nullptr);
    std::thread runner([&] { status = daemon.run(); });
    // Stalled for 1.2 s, then free again.
    std::thread releaser([&] {
      while (stalled_at.load() == 0) std::this_thread::sleep_for(5ms);
      std::this_thread::sleep_for(1200ms);
      release.store(true);
      release.notify_all();
    });
    for (;;) {
      std::string m = socket.receive(10s);
      if (m.empty()) break;
      messages.push_back({m, Clock::now()});
      if (m.rfind("STOPPING=1", 0) == 0) break;
    }
    releaser.join();
    runner.join();
  }
  unsetenv("NOTIFY_SOCKET");
  unsetenv("WATCHDOG_USEC");
  EXPECT_EQ(status, 0);
  ASSERT_GE(messages.size(), 5u);
  ASSERT_EQ(messages.back().text.rfind("STOPPING=1", 0), 0u);

  const Clock::time_point stall{Clock::duration(stalled_at.load())};
  const Clock::time_point freed = stall + 1200ms;
  int before = 0, during = 0, after = 0;
  bool said_why = false;
  for (const auto& m : messages) {
    if (m.text == "WATCHDOG=1") {
      if (m.when < stall) ++before;
      // Pings stop once no rotation was published for stall_timeout_s (0.3 s) and resume when it
      // moves again; 0.3 s of margin each way for the ping period and a loaded machine.
      if (m.when > stall + 600ms && m.when < freed - 100ms) ++during;
      if (m.when > freed) ++after;
    }
    if (m.when > stall + 600ms && m.when < freed &&
        m.text.find("stalled (no rotation published for") != std::string::npos) {
      said_why = true;
    }
  }
  EXPECT_GE(before, 2);
  EXPECT_EQ(during, 0);
  EXPECT_GE(after, 2);
  EXPECT_TRUE(said_why);
}

}  // namespace
}  // namespace lidartag::daemon
