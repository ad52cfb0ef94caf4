// LCM URLs checked before LCM sees them, the log writer that knows what reached the file, and the
// bus that counts every message not delivered: file logs hitting a size limit, multicast without a
// route (in a network namespace), rate-limited reports.
#include "lidartag/daemon/lcm_bus.hpp"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "daemon/namespaces.hpp"
#include "io/file_size_limit.hpp"
#include "lidartag/raw_packet_t.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

std::string temp_path(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartag_lcm_bus");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

std::string error_of(const std::string& url) {
  try {
    (void)parse_lcm_url(url);
  } catch (const LcmError& e) {
    return e.what();
  }
  return "";
}

TEST(LcmUrl, ReadLikeLcmAndRefusedWhereLcmWouldOnlyWarnOrDropMessages) {
  unsetenv("LCM_DEFAULT_URL");
  const LcmUrl d = parse_lcm_url("");
  EXPECT_EQ(d.text, "udpm://239.255.76.67:7667?ttl=0");
  EXPECT_EQ(d.provider, "udpm");
  EXPECT_EQ(d.target, "239.255.76.67:7667");
  EXPECT_EQ(d.option("ttl"), "0");
  setenv("LCM_DEFAULT_URL", "memq://", 1);
  EXPECT_EQ(parse_lcm_url("").text, "memq://");
  unsetenv("LCM_DEFAULT_URL");
  const LcmUrl f = parse_lcm_url("file:///tmp/x.lcmlog?mode=a");
  EXPECT_EQ(f.target, "/tmp/x.lcmlog");
  EXPECT_EQ(f.option("mode"), "a");
  EXPECT_EQ(parse_lcm_url("udpm://239.1.2.3:7700?ttl=1&recv_buf_size=8388608").option("ttl"), "1");

  const std::pair<std::string, std::string> bad[] = {
      {"nosuch://x", "unknown provider 'nosuch'"},
      {"239.255.76.67:7667", "expected PROVIDER://TARGET?OPTIONS"},
      {"udpm://10.0.0.1:7667", "'10.0.0.1' is not an IPv4 multicast group"},
      {"udpm://239.255.76.67:0", "bad port '0'"},
      {"udpm://239.255.76.67:7667?tll=0",
       "unknown option 'tll' for udpm:// (expected ttl, "
       "recv_buf_size)"},
      {"udpm://239.255.76.67:7667?ttl=300", "ttl '300': expected 0..255"},
      {"udpm://239.255.76.67:7667?recv_buf_size=lots", "recv_buf_size 'lots'"},
      {"file:///tmp/x.lcmlog", "add mode=w"},
      {"file:///tmp/x.lcmlog?mode=r", "add mode=w"},
      {"file:///tmp/x.lcmlog?mode=w&speed=2", "unknown option 'speed' for file://"},
      {"file://?mode=w", "no file name"},
      {"memq://x", "memq:// takes no target"},
  };
  for (const auto& [url, message] : bad) {
    SCOPED_TRACE(url);
    const std::string e = error_of(url);
    EXPECT_EQ(e.rfind("LCM URL '" + url + "': ", 0), 0u) << e;
    EXPECT_NE(e.find(message), std::string::npos) << e;
  }
}

raw_packet_t packet(size_t bytes, int n) {
  raw_packet_t p;
  p.utime = n;
  p.receive_time_ns = n;
  p.sensor = "lidar";
  p.source_ipv4 = 0;
  p.port = 2368;
  p.nbytes = static_cast<int32_t>(bytes);
  p.data.assign(bytes, static_cast<uint8_t>(n));
  return p;
}

// Every event of an LCM log, read with LCM's own reader.
std::vector<std::pair<std::string, std::vector<uint8_t>>> read_events(const std::string& path) {
  std::vector<std::pair<std::string, std::vector<uint8_t>>> events;
  lcm::LogFile log(path, "r");
  EXPECT_TRUE(log.good());
  int64_t expected = 0;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    EXPECT_EQ(e->eventnum, expected++);
    const auto* p = static_cast<const uint8_t*>(e->data);
    events.emplace_back(e->channel, std::vector<uint8_t>(p, p + e->datalen));
  }
  return events;
}

TEST(LcmLogWriter, EventsReadBackWithLcmsOwnReader) {
  const std::string path = temp_path("writer.lcmlog");
  {
    LcmLogWriter writer(path, false);
    std::string error;
    for (int i = 0; i < 5; ++i) {
      const std::vector<uint8_t> data(static_cast<size_t>(10 * i), static_cast<uint8_t>(i));
      ASSERT_TRUE(
          writer.write("CH" + std::to_string(i), data.data(), data.size(), 1000 + i, error));
    }
    EXPECT_EQ(writer.events(), 5u);
  }
  {
    LcmLogWriter append(path, true);  // appended events are numbered from 0 again, as LCM does
    std::string error;
    const uint8_t byte = 42;
    ASSERT_TRUE(append.write("MORE", &byte, 1, 2000, error));
  }
  lcm::LogFile log(path, "r");
  std::vector<std::string> channels;
  std::vector<int64_t> times;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    channels.push_back(e->channel);
    times.push_back(e->timestamp);
    EXPECT_EQ(e->datalen, e->channel == "MORE" ? 1 : 10 * (e->channel.back() - '0'));
  }
  EXPECT_EQ(channels, (std::vector<std::string>{"CH0", "CH1", "CH2", "CH3", "CH4", "MORE"}));
  EXPECT_EQ(times, (std::vector<int64_t>{1000, 1001, 1002, 1003, 1004, 2000}));
  EXPECT_THROW(LcmLogWriter("/nonexistent/dir/x.lcmlog", false), LcmError);
  EXPECT_THROW(LcmLogWriter(::testing::TempDir(), false), LcmError);
}

using test::FileSizeLimit;

TEST(LcmLogWriter, AFailedWriteIsCutOffAndWritingResumesWhenSpaceComesBack) {
  const std::string path = temp_path("limited.lcmlog");
  LcmLogWriter writer(path, false);
  std::vector<uint8_t> data(1000, 7);
  std::string error;
  int written = 0, failed = 0;
  {
    FileSizeLimit limit(10'000);  // room for 9 events of 28 + 2 + 1000 bytes, and part of a 10th
    for (int i = 0; i < 20; ++i) {
      if (writer.write("CH", data.data(), data.size(), i, error)) {
        ++written;
      } else {
        ++failed;
      }
    }
  }
  EXPECT_EQ(written, 9);
  EXPECT_EQ(failed, 11);
  EXPECT_NE(error.find("File too large"), std::string::npos) << error;
  EXPECT_EQ(writer.events(), 9u);
  // Whole events only: the torn tenth was cut off.
  EXPECT_EQ(std::filesystem::file_size(path), 9u * (28 + 2 + 1000));
  EXPECT_EQ(read_events(path).size(), 9u);
  // The limit is gone again: writing goes on, numbered after the last whole event.
  ASSERT_TRUE(writer.write("CH", data.data(), data.size(), 99, error));
  EXPECT_EQ(read_events(path).size(), 10u);
}

// Collects what the bus logs.
class LogCapture {
 public:
  LogCapture() : previous_(spdlog::default_logger()) {
    auto logger = std::make_shared<spdlog::logger>(
        "capture", std::make_shared<spdlog::sinks::ostream_sink_mt>(out_));
    logger->set_pattern("%l: %v");
    spdlog::set_default_logger(logger);
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  std::vector<std::string> lines() const { return test::lines_of(out_.str()); }

 private:
  std::ostringstream out_;
  std::shared_ptr<spdlog::logger> previous_;
};

TEST(LcmBus, FileLogWriteErrorsAreCountedNamedAndReportedOnceAPeriod) {
  const std::string path = temp_path("bus.lcmlog");
  LogCapture log;
  LcmBus bus("file://" + path + "?mode=w");
  EXPECT_EQ(bus.provider(), "file");
  size_t attempted = 0;
  {
    FileSizeLimit limit(50'000);
    for (int i = 0; i < 200; ++i, ++attempted) bus.publish("RAW", packet(1206, i));
  }
  const auto events = read_events(path);
  EXPECT_GT(events.size(), 10u);
  EXPECT_EQ(bus.published(), events.size());
  EXPECT_EQ(bus.failures(), attempted - events.size());
  EXPECT_EQ(
      bus.last_error().rfind("RAW: cannot write the LCM log '" + path + "': File too large", 0), 0u)
      << bus.last_error();
  // 150-odd failures within a few milliseconds: one line.
  const auto lines = log.lines();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("warning: LCM: 1 message not delivered (1 in all); last: RAW: cannot "
                           "write the LCM log",
                           0),
            0u)
      << lines[0];
  // Each event that is in the file is one of the messages, whole.
  for (size_t i = 0; i < events.size(); ++i) {
    raw_packet_t got;
    ASSERT_EQ(got.decode(events[i].second.data(), 0, static_cast<int>(events[i].second.size())),
              static_cast<int>(events[i].second.size()));
    EXPECT_EQ(got.utime, static_cast<int64_t>(i));
  }
}

TEST(LcmBus, MemqDeliversAndCountsNothingLost) {
  LcmBus bus("memq://");
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(bus.publish("RAW", packet(100, i)));
  EXPECT_EQ(bus.published(), 10u);
  EXPECT_EQ(bus.failures(), 0u);
  EXPECT_EQ(bus.last_error(), "");
}

// Multicast in a network namespace of its own: with the route, short (one datagram) and long
// (fragmented) messages are delivered; without it both are failures, although LCM 1.3.1 reports
// the long one as sent; with the route back, delivery goes on and is reported.
TEST(LcmBus, MulticastWithoutARouteCountsShortAndFragmentedMessages) {
  LIDARTAG_RUN_IN_NAMESPACE(std::vector<std::string>{"-n"},
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo",
                            temp_path("netns"));
  LogCapture log;
  LcmBus bus("udpm://239.255.76.67:7667?ttl=0");
  const raw_packet_t small = packet(1000, 1), large = packet(200'000, 2);
  EXPECT_TRUE(bus.publish("RAW", small));
  EXPECT_TRUE(bus.publish("RAW", large));
  ASSERT_EQ(std::system("ip route del 224.0.0.0/4 dev lo"), 0);
  EXPECT_FALSE(bus.publish("RAW", small));
  EXPECT_FALSE(bus.publish("RAW", large));
  EXPECT_EQ(bus.failures(), 2u);
  EXPECT_NE(bus.last_error().find("(in fragments) failed: Network is unreachable"),
            std::string::npos)
      << bus.last_error();
  // A new bus now refuses the URL, saying how to add a route.
  try {
    LcmBus again("udpm://239.255.76.67:7667?ttl=0");
    ADD_FAILURE() << "no LcmError";
  } catch (const LcmError& e) {
    EXPECT_NE(std::string(e.what()).find("no route to the multicast group 239.255.76.67"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("ip route add 224.0.0.0/4 dev lo"), std::string::npos);
  }
  ASSERT_EQ(std::system("ip route add 224.0.0.0/4 dev lo"), 0);
  EXPECT_TRUE(bus.publish("RAW", small));
  EXPECT_TRUE(bus.publish("RAW", large));
  EXPECT_EQ(bus.published(), 4u);
  EXPECT_EQ(bus.failures(), 2u);
  const auto lines = log.lines();
  ASSERT_GE(lines.size(), 1u);
  EXPECT_NE(lines[0].find("LCM: 1 message not delivered (1 in all); last: RAW: LCM publish of " +
                          std::to_string(small.getEncodedSize()) +
                          " bytes failed: Network is unreachable"),
            std::string::npos)
      << lines[0];
}

}  // namespace
}  // namespace lidartag::daemon
