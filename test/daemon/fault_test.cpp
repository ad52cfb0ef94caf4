// lidartagd under faults of its surroundings, each with the exit status, the log line and the
// counters expected: output paths on a read-only file system (a tmpfs mounted read-only in the
// test's own mount namespace), the replayed capture deleted during --loop, the log file on a full
// file system (a small tmpfs), SIGHUP when the log file's directory is gone. The faults whose
// expected behaviour is not there yet are in fault_pending_test.cpp; the ones issue 10's tests
// cover (route removed while publishing, LCM log and --record on a full file system, SIGPIPE,
// SIGUSR1/2) are in daemon_setup_e2e_test.cpp.
#include <gtest/gtest.h>

#include <fstream>

#include "daemon/process.hpp"
#include "fake_notify_socket.hpp"
#include "fault_util.hpp"

namespace lidartag::test::faults {
namespace {

#define REQUIRE_DEMO() \
  if (!std::filesystem::exists(kDemo)) GTEST_SKIP() << "no " << kDemo

// Output paths that cannot be written are refused before READY=1 with one line naming the path
// and the system's reason: --record (setup error, exit status 1), --log-file (logging.file,
// exit status 2).
TEST(ReadOnlyPaths, RecordAndLogFileOnAReadOnlyFilesystemAreRefusedWithOneLine) {
  REQUIRE_DEMO();
  IN_NAMESPACES();
  const std::string ro = mount_tmpfs("ro", 64, true);
  struct Case {
    std::vector<std::string> args;
    int status;
    std::string prefix;
    std::string path;
  };
  const std::vector<Case> cases = {
      {{"--record", ro + "/r.pcap"}, 1, "lidartagd: error: ", ro + "/r.pcap"},
      {{"--log-file", ro + "/d.log"}, 2, "lidartagd: config error: logging.file: ", ro + "/d.log"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args.front());
    lidartag::testing::FakeNotifySocket sock(temp("notify.sock"));
    std::vector<std::string> args = {kDaemon, "--config",    kDemoConfig, "--replay",
                                     kDemo,   "--max-speed", "--lcm-url", "memq://"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    Process p(args, {sock.env()}, temp("ro"));
    EXPECT_EQ(p.wait(30s), c.status);
    const auto lines = lines_of(p.err());
    ASSERT_EQ(lines.size(), 1u) << p.err();
    EXPECT_EQ(lines[0].rfind(c.prefix, 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find(c.path), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("Read-only file system"), std::string::npos) << lines[0];
    EXPECT_EQ(sock.receive(100ms), "");  // never READY=1
    EXPECT_FALSE(std::filesystem::exists(c.path));
  }
}

// The capture replayed with --loop is deleted: the pass in progress ends, the next cannot open
// the file: one error naming it, the final status (every rotation assembled was published), exit
// status 1 (a runtime failure, so that systemd's Restart=on-failure applies).
TEST(Loop, CaptureDeletedDuringALoopEndsTheReplayWithAnErrorNamingIt) {
  REQUIRE_DEMO();
  const std::string capture = temp("deleted.pcap"), log = temp("deleted.lcmlog");
  std::filesystem::copy_file(kDemo, capture, std::filesystem::copy_options::overwrite_existing);
  Process p({kDaemon, "--config", kDemoConfig, "--replay", capture, "--loop", "--rate", "2",
             "--lcm-url", "file://" + log + "?mode=w", "--print-detections"},
            {}, temp("deleted"));
  // A few rotations published, then the file goes.
  ASSERT_TRUE(wait_until([&] { return lines_in(p.out()) >= 5; }, 60s)) << p.err();
  std::filesystem::remove(capture);
  EXPECT_EQ(p.wait(30s), 1) << p.err();
  const std::string err = p.err();
  EXPECT_NE(err.find("error: sensor demo: cannot open capture '" + capture + "'"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("final status: demo"), std::string::npos) << err;
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_GE(s->rotations_published, 5);
  EXPECT_EQ(s->rotations_published + s->rotations_dropped, s->rotations_assembled);
  EXPECT_EQ(static_cast<size_t>(s->rotations_published), lines_in(p.out()));
}

// --log-file on a full file system: reported once on standard error with the file and the
// system's reason, the replay publishes every rotation, exit status 0 (the log is not the data).
TEST(FullDisk, LogFileOnAFullFilesystemIsReportedAndTheRunGoesOn) {
  REQUIRE_DEMO();
  IN_NAMESPACES();
  const std::string full = mount_tmpfs("full", 64, false);
  fill(full);
  const std::string logfile = full + "/lidartagd.log", log = temp("fulllog.lcmlog");
  Process p({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed", "--lcm-url",
             "file://" + log + "?mode=w", "--log-file", logfile, "--log-level", "debug",
             "--print-detections"},
            {}, temp("fulllog"));
  EXPECT_EQ(p.wait(60s), 0) << p.err();
  const auto err = lines_of(p.err());
  ASSERT_EQ(err.size(), 1u) << p.err();  // once, not per lost line
  EXPECT_NE(err[0].find(logfile), std::string::npos) << err[0];
  EXPECT_NE(err[0].find("No space left on device"), std::string::npos) << err[0];
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_GT(s->rotations_published, 0);
  EXPECT_EQ(s->rotations_published, s->rotations_assembled);
  EXPECT_EQ(static_cast<size_t>(s->rotations_published), lines_in(p.out()));
}

// SIGHUP (logrotate) when the log file cannot be reopened (its directory was removed): the error
// is reported on standard error, which takes the log over; the replay goes on and publishes every
// rotation; exit status 0.
TEST(Signals, SighupWithTheLogDirectoryGoneIsReportedAndTheRunGoesOn) {
  REQUIRE_DEMO();
  const std::string dir = temp("logdir");
  std::filesystem::create_directories(dir);
  const std::string logfile = dir + "/lidartagd.log", log = temp("sighup.lcmlog");
  Process reference({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--max-speed",
                     "--lcm-url", "memq://", "--print-detections"},
                    {}, temp("sighup_reference"));
  ASSERT_EQ(reference.wait(60s), 0) << reference.err();
  Process p({kDaemon, "--config", kDemoConfig, "--replay", kDemo, "--rate", "0.5", "--lcm-url",
             "file://" + log + "?mode=w", "--log-file", logfile, "--print-detections"},
            {}, temp("sighup"));
  ASSERT_TRUE(
      wait_until([&] { return read_text(logfile).find("running:") != std::string::npos; }, 30s));
  std::filesystem::remove_all(dir);
  p.signal(SIGHUP);
  EXPECT_EQ(p.wait(60s), 0) << p.err();
  const std::string err = p.err();
  EXPECT_NE(err.find("cannot reopen the log"), std::string::npos) << err;
  EXPECT_NE(err.find(logfile), std::string::npos) << err;
  EXPECT_NE(err.find("final status: demo"), std::string::npos) << err;
  EXPECT_EQ(lines_of(p.out()), lines_of(reference.out()));
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->rotations_published, s->rotations_assembled);
  EXPECT_EQ(static_cast<size_t>(s->rotations_published), lines_in(p.out()));
}

// Attack round 2: under a file-size limit (prlimit --fsize) SIGXFSZ killed the daemon (exit 153,
// no final status, the pcap cut mid-packet). A write past the limit is a write error: recording
// stops, the file ends at its last whole packet, the run goes on, exit status 3.
TEST(FileSizeLimit, RecordPastTheLimitIsAWriteErrorNotAKill) {
  REQUIRE_DEMO();
  if (!std::filesystem::exists("/usr/bin/prlimit")) GTEST_SKIP() << "no /usr/bin/prlimit";
  const std::string record = temp("fsize.pcap"), log = temp("fsize.lcmlog");
  std::filesystem::remove(record);
  // The LCM log is written under the limit too (its failures are counted: exit status 3 anyway).
  Process p(
      {"/usr/bin/prlimit", "--fsize=100000", "--", kDaemon, "--config", kDemoConfig, "--replay",
       kDemo, "--max-speed", "--record", record, "--lcm-url", "file://" + log + "?mode=w"},
      {}, temp("fsize"));
  EXPECT_EQ(p.wait(60s), 3) << p.err();
  EXPECT_NE(p.err().find("final status"), std::string::npos) << p.err();
  EXPECT_NE(p.err().find("recording " + record + " failed"), std::string::npos) << p.err();
  // Whole records only: the file reads to its end without a truncated record.
  driver::PcapSource source(record);
  driver::RawPacket packet;
  size_t packets = 0;
  while (source.next(packet, 0ms) == driver::ReadStatus::kPacket) ++packets;
  EXPECT_GT(packets, 10u);
  EXPECT_EQ(source.stats().truncated, 0u);
  EXPECT_EQ(source.error(), "");
  EXPECT_LE(std::filesystem::file_size(record), 100000u);
}

// Attack round 2: a record in the middle of a capture with an impossible length ended the
// replay there, exit 0, "ended (the source ended)". The final status names the record and what
// was not read, and the exit status says data was lost.
TEST(CorruptReplay, ARecordThatStopsTheReplayIsNamedInTheFinalStatusAndExitStatus3) {
  REQUIRE_DEMO();
  const std::string capture = temp("corrupt.pcap"), log = temp("corrupt.lcmlog");
  std::filesystem::copy_file(kDemo, capture, std::filesystem::copy_options::overwrite_existing);
  {
    // Record 100's caplen (classic pcap: 24-byte file header, 16-byte record headers) = 1 MiB.
    std::fstream f(capture, std::ios::in | std::ios::out | std::ios::binary);
    uint64_t at = 24;
    for (int i = 0; i < 99; ++i) {
      f.seekg(static_cast<std::streamoff>(at + 8));
      uint32_t caplen = 0;
      f.read(reinterpret_cast<char*>(&caplen), 4);
      at += 16 + caplen;
    }
    const uint32_t huge = 1u << 20;
    f.seekp(static_cast<std::streamoff>(at + 8));
    f.write(reinterpret_cast<const char*>(&huge), 4);
  }
  Process p({kDaemon, "--config", kDemoConfig, "--replay", capture, "--max-speed", "--lcm-url",
             "file://" + log + "?mode=w"},
            {}, temp("corrupt"));
  EXPECT_EQ(p.wait(60s), 3) << p.err();
  const auto s = last_status(log);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->state, int8_t{lidartag::status_t::STATE_ENDED});
  EXPECT_NE(s->reason.find("is unreadable after record 99"), std::string::npos) << s->reason;
  EXPECT_NE(s->reason.find("bytes not read"), std::string::npos) << s->reason;
}

}  // namespace
}  // namespace lidartag::test::faults
