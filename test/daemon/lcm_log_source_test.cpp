// Raw-packet replay from an LCM log: good messages become packets, malformed ones are counted and
// skipped, never fatal.
#include "lidartag/daemon/lcm_log_source.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <random>

#include "lidartag/daemon/messages.hpp"

namespace lidartag::daemon {
namespace {

using namespace std::chrono_literals;

void write_event(lcm::LogFile& log, const std::string& channel, const std::vector<uint8_t>& bytes,
                 int64_t t) {
  lcm::LogEvent e{};
  e.eventnum = 0;
  e.timestamp = t;
  e.channel = channel;
  e.datalen = static_cast<int32_t>(bytes.size());
  e.data = const_cast<uint8_t*>(bytes.data());
  ASSERT_EQ(log.writeEvent(&e), 0);
}

std::vector<uint8_t> encoded(int64_t time_ns, uint16_t port, std::vector<uint8_t> payload) {
  driver::RawPacket p;
  p.payload = payload;
  p.receive_time_ns = time_ns;
  p.destination_port = port;
  lidartag::raw_packet_t msg;
  fill_raw_packet(p, "lidar", msg);
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// The logs below are written to TempDir under this process's id; removed when the program ends.
class RemoveLogs : public ::testing::Environment {
 public:
  void TearDown() override {
    for (const char* name : {"_raw_replay.lcmlog", "_raw_times.lcmlog", "_raw_corrupt.lcmlog"}) {
      std::remove((::testing::TempDir() + "/" + std::to_string(::getpid()) + name).c_str());
    }
  }
};
[[maybe_unused]] ::testing::Environment* const remove_logs =
    ::testing::AddGlobalTestEnvironment(new RemoveLogs);

std::string make_log() {
  const std::string path =
      ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_raw_replay.lcmlog";
  lcm::LogFile log(path, "w");
  EXPECT_TRUE(log.good());
  write_event(log, "LIDARTAG_RAW", encoded(1'000'000'000, 2368, {1, 2, 3}), 1);
  write_event(log, "LIDARTAG_RAW", {0xde, 0xad, 0xbe, 0xef, 1, 2}, 2);  // wrong hash
  auto truncated = encoded(1'100'000'000, 2368, {4, 5, 6, 7});
  truncated.resize(truncated.size() - 3);  // right hash, cut short
  write_event(log, "LIDARTAG_RAW", truncated, 3);
  auto bad_length = encoded(1'150'000'000, 2368, {4});
  bad_length[bad_length.size() - 5] = 0x7f;  // nbytes claims ~2 GB
  write_event(log, "LIDARTAG_RAW", bad_length, 4);
  write_event(log, "OTHER", encoded(1'200'000'000, 2368, {9}), 5);
  write_event(log, "LIDARTAG_RAW", encoded(1'300'000'000, 8308, {7, 7}), 6);
  return path;
}

TEST(LcmLogSource, DeliversGoodPacketsAndCountsMalformedOnes) {
  LcmLogSource source(make_log(), {});
  driver::RawPacket p;
  ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
  EXPECT_EQ(p.receive_time_ns, 1'000'000'000);
  EXPECT_EQ(p.destination_port, 2368);
  EXPECT_EQ(std::vector<uint8_t>(p.payload.begin(), p.payload.end()),
            (std::vector<uint8_t>{1, 2, 3}));
  ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
  EXPECT_EQ(p.destination_port, 8308);
  EXPECT_EQ(p.payload.size(), 2u);
  EXPECT_EQ(source.next(p, 10ms), driver::ReadStatus::kEnd);
  EXPECT_EQ(source.stats().packets, 2u);
  EXPECT_EQ(source.stats().malformed, 3u);
  EXPECT_EQ(source.stats().ignored, 1u);
}

TEST(LcmLogSource, LoopKeepsTimeGrowing) {
  LcmLogSourceOptions o;
  o.loop = true;
  LcmLogSource source(make_log(), o);
  std::vector<int64_t> times;
  driver::RawPacket p;
  for (int i = 0; i < 6; ++i) {
    ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
    times.push_back(p.receive_time_ns);
  }
  EXPECT_TRUE(std::is_sorted(times.begin(), times.end()));
  EXPECT_GT(times[2], times[1]);
  EXPECT_EQ(times[2] - times[0], 600'000'000);  // duration 300 ms + last interval 300 ms
}

TEST(LcmLogSource, PacedReplayWaits) {
  LcmLogSourceOptions o;
  o.rate = 1.0;
  LcmLogSource source(make_log(), o);
  driver::RawPacket p;
  ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
  // The second packet is due 300 ms after the first: not within 10 ms.
  EXPECT_EQ(source.next(p, 10ms), driver::ReadStatus::kTimeout);
  ASSERT_EQ(source.next(p, 1000ms), driver::ReadStatus::kPacket);
  EXPECT_EQ(p.destination_port, 8308);
}

TEST(LcmLogSource, ImpossibleReceiveTimesAreCountedAsMalformed) {
  // receive_time_ns is any int64 in a corrupt message; downstream time arithmetic must not
  // overflow on it.
  const std::string path =
      ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_raw_times.lcmlog";
  {
    lcm::LogFile log(path, "w");
    write_event(log, "LIDARTAG_RAW", encoded(std::numeric_limits<int64_t>::max(), 2368, {1}), 1);
    write_event(log, "LIDARTAG_RAW", encoded(std::numeric_limits<int64_t>::min(), 2368, {2}), 2);
    write_event(log, "LIDARTAG_RAW", encoded(-1, 2368, {3}), 3);
    write_event(log, "LIDARTAG_RAW", encoded(driver::kMaxReceiveTimeNs, 2368, {4}), 4);
    write_event(log, "LIDARTAG_RAW", encoded(1'700'000'000'000'000'000, 2368, {5}), 5);
  }
  LcmLogSourceOptions o;
  o.loop = true;
  LcmLogSource source(path, o);
  driver::RawPacket p;
  for (int pass = 0; pass < 3; ++pass) {
    ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
    EXPECT_EQ(p.payload[0], 5);
    EXPECT_GE(p.receive_time_ns, 1'700'000'000'000'000'000);
  }
  EXPECT_EQ(source.stats().malformed, 12u);  // 4 per pass
}

TEST(LcmLogSource, RandomlyCorruptedMessagesAreCountedNeverFatal) {
  const std::string path =
      ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_raw_corrupt.lcmlog";
  std::mt19937 rng(23);
  const int events = 300;
  {
    lcm::LogFile log(path, "w");
    for (int k = 0; k < events; ++k) {
      std::vector<uint8_t> payload(1 + rng() % 1300);
      for (auto& b : payload) b = static_cast<uint8_t>(rng());
      auto bytes = encoded(1'000'000'000 + k * 1'000'000, k % 2 ? 2368 : 8308, payload);
      const int damage = static_cast<int>(rng() % 4);
      for (int d = 0; d < damage; ++d) {
        // Mostly the header (hash, times, string length, port, nbytes), sometimes anywhere.
        const size_t at =
            rng() % 2 ? rng() % std::min<size_t>(bytes.size(), 48) : rng() % bytes.size();
        bytes[at] = static_cast<uint8_t>(rng());
      }
      if (rng() % 8 == 0) bytes.resize(rng() % bytes.size());
      write_event(log, "LIDARTAG_RAW", bytes, k);
    }
  }
  LcmLogSource source(path, {});
  driver::RawPacket p;
  uint64_t delivered = 0;
  for (int k = 0; k <= events; ++k) {
    const auto status = source.next(p, 10ms);
    if (status == driver::ReadStatus::kEnd) break;
    ASSERT_EQ(status, driver::ReadStatus::kPacket);
    ++delivered;
    EXPECT_TRUE(p.destination_port > 0);
    EXPECT_TRUE(p.receive_time_ns >= 0 && p.receive_time_ns < driver::kMaxReceiveTimeNs);
  }
  EXPECT_EQ(source.next(p, 10ms), driver::ReadStatus::kEnd);
  EXPECT_EQ(delivered + source.stats().malformed, static_cast<uint64_t>(events));
  EXPECT_GT(delivered, 0u);
  EXPECT_GT(source.stats().malformed, 0u);
  EXPECT_EQ(source.stats().truncated, 0u);
}

TEST(LcmLogSource, LogCutInsideAnEventEndsAndIsCountedAsTruncated) {
  const std::string path = make_log();
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 4);  // the last event loses its last bytes
  LcmLogSource source(path, {});
  driver::RawPacket p;
  ASSERT_EQ(source.next(p, 10ms), driver::ReadStatus::kPacket);
  EXPECT_EQ(source.next(p, 10ms), driver::ReadStatus::kEnd);
  EXPECT_EQ(source.stats().packets, 1u);
  EXPECT_EQ(source.stats().truncated, 1u);
  // A whole log is not truncated.
  LcmLogSource whole(make_log(), {});
  while (whole.next(p, 10ms) == driver::ReadStatus::kPacket) {
  }
  EXPECT_EQ(whole.stats().truncated, 0u);
}

// A corrupt header at the end of a log that claims ~2 GB of data: LCM would allocate that much
// before finding the file short (and, where the allocation fails, read into a null pointer).
std::string log_ending_in_a_huge_claim() {
  const std::string path = make_log();
  std::FILE* f = std::fopen(path.c_str(), "ab");
  EXPECT_NE(f, nullptr);
  const std::string channel = "LIDARTAG_RAW";
  std::vector<uint8_t> h = {0xED, 0xA1, 0xDA, 0x01};                    // sync word
  for (int i = 0; i < 16; ++i) h.push_back(i == 7 || i == 15 ? 9 : 0);  // event 9, time 9
  for (uint32_t v : {static_cast<uint32_t>(channel.size()), 0x7ffffff0U})
    for (int b = 3; b >= 0; --b) h.push_back(static_cast<uint8_t>(v >> (8 * b)));
  h.insert(h.end(), channel.begin(), channel.end());
  h.insert(h.end(), 64, 0xab);  // some of the claimed data
  EXPECT_EQ(std::fwrite(h.data(), 1, h.size(), f), h.size());
  std::fclose(f);
  return path;
}

TEST(LcmLogSource, AnEventClaimingMoreThanTheFileHoldsEndsTheReplayAsTruncated) {
  LcmLogSource source(log_ending_in_a_huge_claim(), {});
  driver::RawPacket p;
  int packets = 0;
  while (source.next(p, 10ms) == driver::ReadStatus::kPacket) ++packets;
  EXPECT_EQ(packets, 2);  // make_log's two good packets, then the end
  EXPECT_EQ(source.stats().truncated, 1u);
  EXPECT_EQ(source.events(), 6u);  // the huge one is not an event read
}

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__) && \
    !(defined(__has_feature) &&                                        \
      (__has_feature(address_sanitizer) || __has_feature(thread_sanitizer)))
// Under an address-space limit (ulimit -v, systemd's LimitAS=) the claimed ~2 GB cannot be had:
// the replay still ends normally. (Sanitizers reserve terabytes of shadow memory: not there.)
int replay_under_a_1_gib_limit(const std::string& path) {
  rlimit limit{};
  limit.rlim_cur = limit.rlim_max = 1UL << 30;
  if (::setrlimit(RLIMIT_AS, &limit) != 0) return 3;
  LcmLogSource source(path, {});
  driver::RawPacket p;
  while (source.next(p, 10ms) == driver::ReadStatus::kPacket) {
  }
  return source.stats().truncated == 1 ? 0 : 2;
}

TEST(LcmLogSourceDeathTest, AHugeClaimUnderAnAddressSpaceLimitEndsTheReplayNormally) {
  const std::string path = log_ending_in_a_huge_claim();
  EXPECT_EXIT(std::_Exit(replay_under_a_1_gib_limit(path)), ::testing::ExitedWithCode(0), "");
}
#endif

TEST(LcmLogSource, MissingFileIsASetupError) {
  EXPECT_THROW(LcmLogSource("/nonexistent/x.lcmlog", {}), driver::IoError);
}

}  // namespace
}  // namespace lidartag::daemon
