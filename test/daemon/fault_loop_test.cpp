// More faults of the surroundings (part of test_daemon_faults): an LCM log on a read-only file
// system (refused before READY=1 with one line naming the path), --loop over a capture shorter
// than a second, and one truncated while looping (each pass replayed at its pace, the cut record
// counted). Each states the exit status, the log line and the counter expected.
#include <gtest/gtest.h>

#include "daemon/process.hpp"
#include "fake_notify_socket.hpp"
#include "fault_util.hpp"

namespace lidartag::test::faults {
namespace {

#define REQUIRE_DEMO() \
  if (!std::filesystem::exists(kDemo)) GTEST_SKIP() << "no " << kDemo

// An LCM log (file:// URL) on a read-only file system: one line naming the path and the reason,
// before READY=1, exit status 1.
TEST(ReadOnlyPaths, LcmLogOnAReadOnlyFilesystemIsRefusedWithOneLine) {
  REQUIRE_DEMO();
  IN_NAMESPACES();
  const std::string ro = mount_tmpfs("ro", 64, true);
  lidartag::testing::FakeNotifySocket sock(temp("notify.sock"));
  Process p({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url",
             "file://" + ro + "/x.lcmlog?mode=w"},
            {sock.env()}, temp("ro_lcm"));
  EXPECT_EQ(p.wait(30s), 1);
  const auto lines = lines_of(p.err());
  ASSERT_EQ(lines.size(), 1u) << p.err();
  EXPECT_EQ(lines[0].rfind("lidartagd: error: ", 0), 0u) << lines[0];
  EXPECT_NE(lines[0].find(ro + "/x.lcmlog"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find("Read-only file system"), std::string::npos) << lines[0];
  EXPECT_EQ(sock.receive(100ms), "");
}

// Rotations published in `seconds` of a looping replay at the recorded pace, after `started`
// lines.
size_t rotations_within(Process& p, size_t started, std::chrono::milliseconds seconds) {
  std::this_thread::sleep_for(seconds);
  return lines_in(p.out()) - started;
}

// A capture of 0.4 s (four rotations at 600 rpm) looped at its pace: ten rotations a second,
// pass after pass (the loop seam may cost one partial rotation per pass, no more).
TEST(Loop, ACaptureShorterThanASecondLoopsAtItsPace) {
  REQUIRE_DEMO();
  const std::string capture = temp("short.pcap"), log = temp("short.lcmlog");
  cut_demo(capture, 0.4);
  Process p({kDaemon, "--config", kDemoConfig, "--replay", capture, "--loop", "--rate", "1",
             "--lcm-url", "file://" + log + "?mode=w", "--print-detections"},
            {}, temp("short"));
  ASSERT_TRUE(wait_until([&] { return lines_in(p.out()) >= 2; }, 30s)) << p.err();
  const size_t in_3s = rotations_within(p, lines_in(p.out()), 3000ms);
  p.signal(SIGTERM);
  EXPECT_EQ(p.wait(30s), 0) << p.err();
  // 30 at 10 per second; at least 3 of every 4 per pass.
  EXPECT_GE(in_3s, 22u) << p.err();
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_GE(s->rotations_published, 22);
  // The seams' partial rotations are not losses: the final status names them apart.
  ASSERT_GT(s->rotations_seam, 0);
  EXPECT_NE(p.err().find(" 0 dropped, " + std::to_string(s->rotations_seam) +
                         " loop-seam partials (not published by design)"),
            std::string::npos)
      << p.err();
}

// The capture is truncated to half while looping: the pass in progress ends at the cut record
// (counted as malformed), the following passes replay the half that is left, at its pace.
TEST(Loop, CaptureTruncatedDuringALoopKeepsReplayingAndCountsTheCutRecord) {
  REQUIRE_DEMO();
  const std::string capture = temp("truncated.pcap"), log = temp("truncated.lcmlog");
  std::filesystem::copy_file(kDemo, capture, std::filesystem::copy_options::overwrite_existing);
  Process p({kDaemon, "--config", kDemoConfig, "--replay", capture, "--loop", "--rate", "1",
             "--lcm-url", "file://" + log + "?mode=w", "--print-detections"},
            {}, temp("truncated"));
  ASSERT_TRUE(wait_until([&] { return lines_in(p.out()) >= 3; }, 30s)) << p.err();
  // Half the file, in the middle of a record.
  std::filesystem::resize_file(capture, std::filesystem::file_size(capture) / 2 + 7);
  const size_t in_4s = rotations_within(p, lines_in(p.out()), 4000ms);
  p.signal(SIGTERM);
  EXPECT_EQ(p.wait(30s), 0) << p.err();
  // Half a second of capture (five rotations) per pass: about 40 in 4 s; the seams may cost one
  // partial rotation each.
  EXPECT_GE(in_4s, 25u) << p.err();
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_GE(s->packets_malformed, 1);  // the cut record, once per pass
  EXPECT_EQ(s->rotations_published + s->rotations_dropped, s->rotations_assembled);
}

}  // namespace
}  // namespace lidartag::test::faults
