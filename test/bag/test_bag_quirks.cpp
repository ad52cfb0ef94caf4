// Real files' quirks and the time window, on bags written by the tests themselves
// (synthetic_bags.hpp, and a rosbag2 sqlite3 folder made with sqlite): chunks out of time order
// (delivered in file order, as docs/bags.md says), a truncated final chunk (what can be read is,
// the loss counted and described), an empty serialization_format column, metadata.yaml times that
// disagree with the messages' own, and --start/--duration counted from the earliest message.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "bag/bag_files.hpp"
#include "bag/synthetic_bags.hpp"
#include "lidartag/driver/bag/message_reader.hpp"

namespace lidartag::driver::bag {
namespace {

namespace syn = synthetic;
using testing::TempDir;
using testing::write_bytes;

constexpr int64_t kT0 = 1'700'000'000'000'000'000;  // ns since epoch
constexpr int64_t kStep = 100'000'000;              // 0.1 s

const std::vector<syn::Topic> kTopics = {{"/points", "sensor_msgs/PointCloud2"},
                                         {"/imu", "sensor_msgs/Imu"}};

// Ten messages, 0.1 s apart, alternating topics; the payload is the message's number.
syn::Message message(int k) {
  return {k % 2 == 0 ? "/points" : "/imu", kT0 + k * kStep, {static_cast<uint8_t>(k)}};
}
// Two chunks: messages 5-9 first in the file, then 0-4 (out of time order).
syn::Chunks out_of_order() {
  syn::Chunks c(2);
  for (int k = 5; k < 10; ++k) c[0].push_back(message(k));
  for (int k = 0; k < 5; ++k) c[1].push_back(message(k));
  return c;
}

struct Read {
  std::vector<int> numbers;
  std::vector<int64_t> times;
  ReadStats stats;
  std::string error;
  std::optional<int64_t> start;
};

Read read_all(const std::string& path, ReaderOptions options = {}) {
  Read r;
  const auto reader = open_bag(path, options);
  BagMessage m;
  while (reader->next(m)) {
    r.numbers.push_back(m.data.empty() ? -1 : m.data[0]);
    r.times.push_back(m.time_ns);
  }
  r.stats = reader->stats();
  r.error = reader->error();
  r.start = reader->start_time_ns();
  return r;
}

struct Format {
  const char* name;
  syn::Bytes (*write)(const std::vector<syn::Topic>&, const syn::Chunks&, bool);
};
const Format kFormats[] = {
    {"ros1", [](const std::vector<syn::Topic>& t, const syn::Chunks& c,
                bool index) { return syn::ros1_bag(t, c, index); }},
    {"mcap", [](const std::vector<syn::Topic>& t, const syn::Chunks& c,
                bool index) { return syn::mcap_file(t, c, index); }},
};

TEST(BagQuirks, ChunksOutOfTimeOrderAreDeliveredInFileOrderWithTheirOwnTimes) {
  TempDir dir;
  for (const Format& f : kFormats) {
    SCOPED_TRACE(f.name);
    const std::string path = dir.file(std::string("ooo.") + f.name);
    write_bytes(path, f.write(kTopics, out_of_order(), true));
    const Read r = read_all(path);
    EXPECT_EQ(r.numbers, (std::vector<int>{5, 6, 7, 8, 9, 0, 1, 2, 3, 4}));
    for (size_t i = 0; i < r.numbers.size(); ++i) EXPECT_EQ(r.times[i], kT0 + r.numbers[i] * kStep);
    EXPECT_TRUE(r.error.empty()) << r.error;
    // The bag's start is its earliest message, though it is not the first in the file.
    ASSERT_TRUE(r.start.has_value());
    EXPECT_EQ(*r.start, kT0);
  }
}

TEST(BagQuirks, TimeWindowCountsFromTheEarliestMessageAndCountsWhatItLeavesOut) {
  TempDir dir;
  for (const Format& f : kFormats) {
    SCOPED_TRACE(f.name);
    const std::string path = dir.file(std::string("window.") + f.name);
    write_bytes(path, f.write(kTopics, out_of_order(), true));
    ReaderOptions o;
    o.start_s = 0.25;
    o.duration_s = 0.3;  // messages 3, 4, 5 (0.3, 0.4, 0.5 s)
    Read r = read_all(path, o);
    EXPECT_EQ(r.numbers, (std::vector<int>{5, 3, 4}));  // file order
    EXPECT_EQ(r.stats.outside_window, 7u);
    EXPECT_EQ(r.times.front(), kT0 + 5 * kStep);  // the recorded times are kept
    // With a topic: only that topic's messages outside the window are counted.
    o.topics = {"/points"};
    r = read_all(path, o);
    EXPECT_EQ(r.numbers, (std::vector<int>{4}));
    EXPECT_EQ(r.stats.outside_window, 4u);
    // Start only: to the end; duration only: from the start.
    ReaderOptions start_only;
    start_only.start_s = 0.75;
    EXPECT_EQ(read_all(path, start_only).numbers, (std::vector<int>{8, 9}));
    ReaderOptions duration_only;
    duration_only.duration_s = 0.15;
    EXPECT_EQ(read_all(path, duration_only).numbers, (std::vector<int>{0, 1}));
  }
}

TEST(BagQuirks, WithoutIndexOrSummaryTheWindowCountsFromTheFirstMessageRead) {
  TempDir dir;
  for (const Format& f : kFormats) {
    SCOPED_TRACE(f.name);
    const std::string path = dir.file(std::string("unindexed.") + f.name);
    write_bytes(path, f.write(kTopics, out_of_order(), false));
    ReaderOptions o;
    o.duration_s = 0.25;  // from message 5: 5, 6, 7; the earlier ones (0-4) are before it
    const Read r = read_all(path, o);
    EXPECT_EQ(r.numbers, (std::vector<int>{5, 6, 7}));
    EXPECT_EQ(r.stats.outside_window, 7u);
    ASSERT_TRUE(r.start.has_value());
    EXPECT_EQ(*r.start, kT0 + 5 * kStep);
  }
}

TEST(BagQuirks, TruncatedFinalChunkReadsTheChunksBeforeItAndSaysWhatWasLost) {
  TempDir dir;
  for (const Format& f : kFormats) {
    SCOPED_TRACE(f.name);
    syn::Chunks chunks(3);
    for (int k = 0; k < 9; ++k) chunks[static_cast<size_t>(k / 3)].push_back(message(k));
    // Unindexed (a recording cut short has neither index nor summary), then cut inside the last
    // chunk, a few bytes before its end.
    const syn::Bytes whole = f.write(kTopics, chunks, false);
    // Where the last chunk ends in `whole`: before the index/summary tail, which, without index
    // or summary, is the MCAP DataEnd + footer + magic, or nothing for ROS 1.
    const size_t tail = std::string(f.name) == "mcap" ? 13 + 29 + 8 : 0;
    const size_t cut = whole.size() - tail - 5;
    const syn::Bytes truncated(whole.begin(), whole.begin() + static_cast<std::ptrdiff_t>(cut));
    const std::string path = dir.file(std::string("cut.") + f.name);
    write_bytes(path, truncated);
    const Read r = read_all(path);
    EXPECT_EQ(r.numbers, (std::vector<int>{0, 1, 2, 3, 4, 5}));
    EXPECT_EQ(r.stats.truncated, 1u);
    EXPECT_EQ(r.stats.chunks, 2u);
    EXPECT_NE(r.error.find("the rest"), std::string::npos) << r.error;
  }
}

// A rosbag2 sqlite3 folder: one topic with an empty serialization_format, and a metadata.yaml
// whose times say 2021 while the messages say 2023.
void make_rosbag2(const std::string& folder, const std::vector<int64_t>& times) {
  std::filesystem::create_directories(folder);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((folder + "/bag_0.db3").c_str(), &db), SQLITE_OK);
  const char* schema =
      "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
      "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
      "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp "
      "INTEGER NOT NULL, data BLOB NOT NULL);"
      "INSERT INTO topics VALUES(1, '/points', 'sensor_msgs/msg/PointCloud2', '', '');";
  ASSERT_EQ(sqlite3_exec(db, schema, nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  for (size_t k = 0; k < times.size(); ++k) {
    const std::string insert = "INSERT INTO messages(topic_id, timestamp, data) VALUES(1, " +
                               std::to_string(times[k]) + ", x'0" + std::to_string(k) + "')";
    ASSERT_EQ(sqlite3_exec(db, insert.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  }
  sqlite3_close(db);
  std::ofstream(folder + "/metadata.yaml")
      << "rosbag2_bagfile_information:\n  version: 4\n  storage_identifier: sqlite3\n"
         "  relative_file_paths: [bag_0.db3]\n"
         "  duration: {nanoseconds: 5000000000}\n"
         "  starting_time: {nanoseconds_since_epoch: 1610000000000000000}\n"
         "  message_count: 99\n"
         "  topics_with_message_count: []\n  compression_format: \"\"\n"
         "  compression_mode: \"\"\n";
}

TEST(BagQuirks, Rosbag2EmptySerializationFormatAndMetadataTimesThatDisagree) {
  TempDir dir;
  const std::string folder = dir.file("rosbag2");
  // Stored out of time order: sqlite3 bags are read in timestamp order.
  make_rosbag2(folder, {kT0 + 3 * kStep, kT0, kT0 + kStep, kT0 + 2 * kStep});
  const auto reader = open_bag(folder);
  ASSERT_EQ(reader->connections().size(), 1u);
  EXPECT_EQ(reader->connections()[0].encoding, Encoding::kCdr);  // empty column: CDR
  EXPECT_EQ(reader->connections()[0].count, 4u);                 // not metadata.yaml's 99
  ASSERT_TRUE(reader->start_time_ns().has_value());
  EXPECT_EQ(*reader->start_time_ns(), kT0);  // not metadata.yaml's 2021
  Read r = read_all(folder);
  EXPECT_EQ(r.numbers, (std::vector<int>{1, 2, 3, 0}));
  EXPECT_EQ(r.times, (std::vector<int64_t>{kT0, kT0 + kStep, kT0 + 2 * kStep, kT0 + 3 * kStep}));
  ReaderOptions o;
  o.start_s = 0.1;
  o.duration_s = 0.2;
  r = read_all(folder, o);
  EXPECT_EQ(r.numbers, (std::vector<int>{2, 3}));
  EXPECT_EQ(r.stats.outside_window, 2u);
}

TEST(BagQuirks, ProblemsQuotedFromTheFileStayOneLine) {
  // A chunk compression named with a newline (found by fuzz_mcap): skipped, described in one line.
  TempDir dir;
  const syn::Compression odd{"lz\n4", [](const syn::Bytes& b) { return b; }};
  const std::string path = dir.file("odd.mcap");
  write_bytes(path, syn::mcap_file(kTopics, out_of_order(), true, false, odd));
  const Read r = read_all(path);
  EXPECT_TRUE(r.numbers.empty());
  EXPECT_EQ(r.stats.skipped_chunks, 2u);
  EXPECT_EQ(r.error.find('\n'), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("unknown compression 'lz\\x0a4'"), std::string::npos) << r.error;
}

TEST(BagQuirks, WindowProblemsAreNamed) {
  EXPECT_EQ(window_problem(0, 1), "");
  EXPECT_NE(window_problem(-1, 1).find("--start"), std::string::npos);
  EXPECT_NE(window_problem(0, 0).find("--duration"), std::string::npos);
}

}  // namespace
}  // namespace lidartag::driver::bag
