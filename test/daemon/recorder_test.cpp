// The --record file on a full disk: recording stops with one error line, and what the recorder
// reports is what the file holds.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <sstream>

#include "daemon/process.hpp"
#include "io/file_size_limit.hpp"
#include "lidartag/daemon/tap_source.hpp"
#include "lidartag/driver/io/pcap_source.hpp"
#include "temp_dir.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

std::string temp_path(const std::string& name) {
  static const lidartag::test::ProcessTempDir scratch_dir("lidartag_recorder");
  const std::string& dir = scratch_dir.path();
  return dir + "/" + name;
}

size_t packets_in(const std::string& path, std::vector<int64_t>* times = nullptr) {
  driver::PcapSource source(path);
  driver::RawPacket packet;
  size_t n = 0;
  while (source.next(packet, 10ms) == driver::ReadStatus::kPacket) {
    ++n;
    if (times != nullptr) times->push_back(packet.receive_time_ns);
  }
  return n;
}

TEST(PcapRecorder, AFullDiskStopsRecordingOnceAndCountsWhatIsNotInTheFile) {
  const std::string path = temp_path("full.pcap");
  std::ostringstream log;
  auto previous = spdlog::default_logger();
  auto logger = std::make_shared<spdlog::logger>(
      "capture", std::make_shared<spdlog::sinks::ostream_sink_mt>(log));
  logger->set_pattern("%l: %v");
  spdlog::set_default_logger(logger);

  const std::vector<uint8_t> payload(1206, 0x5A);
  constexpr uint64_t kPackets = 3000;
  {
    PcapRecorder recorder(path);
    test::FileSizeLimit limit(1'000'000);  // about 790 packets
    for (uint64_t i = 0; i < kPackets; ++i) {
      driver::RawPacket p;
      p.payload = payload;
      p.receive_time_ns = static_cast<int64_t>(i) * 1'000'000'000;
      p.destination_port = 2368;
      recorder.write(p);
    }
    recorder.close();
    EXPECT_TRUE(recorder.failed());
    const uint64_t recorded = recorder.records();
    EXPECT_GT(recorded, 500u);
    EXPECT_LT(recorded, 800u);
    EXPECT_EQ(recorder.missed(), kPackets - recorded);
    EXPECT_EQ(recorder.error(),
              "cannot write '" + path + "': File too large; the file holds the first " +
                  std::to_string(recorded) + " packets, " + std::to_string(kPackets - recorded) +
                  " received later are not in it");
    // What it says is in the file is in the file: the first `recorded` packets, in order.
    std::vector<int64_t> times;
    EXPECT_EQ(packets_in(path, &times), recorded);
    for (size_t i = 0; i < times.size(); ++i) {
      EXPECT_EQ(times[i], static_cast<int64_t>(i) * 1'000'000'000);
    }
  }
  spdlog::set_default_logger(previous);
  // Logged once, when it happened.
  const auto lines = test::lines_of(log.str());
  ASSERT_EQ(lines.size(), 1u) << log.str();
  EXPECT_EQ(lines[0].rfind("error: recording " + path + " stopped: cannot write '" + path +
                               "': File too large; the file holds the first ",
                           0),
            0u)
      << lines[0];
}

TEST(PcapRecorder, EverythingWrittenIsInTheFileAfterClose) {
  const std::string path = temp_path("ok.pcap");
  PcapRecorder recorder(path);
  const std::vector<uint8_t> payload(100, 1);
  for (int i = 0; i < 10; ++i) {
    driver::RawPacket p;
    p.payload = payload;
    p.destination_port = 2368;
    recorder.write(p);
  }
  recorder.close();
  EXPECT_FALSE(recorder.failed());
  EXPECT_EQ(recorder.error(), "");
  EXPECT_EQ(recorder.records(), 10u);
  EXPECT_EQ(recorder.missed(), 0u);
  EXPECT_EQ(packets_in(path), 10u);
}

}  // namespace
}  // namespace lidartag::daemon
