// The MCAP writer: files of every compression and chunk size pass the format's invariants
// (mcap_check.hpp) and read back, message for message, through the project's MCAP reader.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "foxglove/mcap_check.hpp"
#include "lidartag/driver/bag/mcap_writer.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "lidartag/foxglove/scene_recorder.hpp"

namespace lidartag::driver::bag {
namespace {

namespace fs = std::filesystem;

fs::path temp_file(const std::string& name) {
  return fs::temp_directory_path() / ("lidartag_mcap_" + std::to_string(::getpid()) + "_" + name);
}

struct Sent {
  uint16_t channel;
  uint64_t time;
  std::vector<uint8_t> data;
};

TEST(McapWriter, EveryCompressionAndChunkSizeReadsBackAndPassesTheInvariants) {
  for (const auto compression :
       {McapCompression::kNone, McapCompression::kZstd, McapCompression::kLz4}) {
    for (const size_t chunk_bytes : {size_t{1}, size_t{700}, size_t{1} << 20}) {
      SCOPED_TRACE(std::to_string(static_cast<int>(compression)) + " chunk " +
                   std::to_string(chunk_bytes));
      const auto path = temp_file("roundtrip.mcap");
      McapWriterOptions o;
      o.compression = compression;
      o.chunk_bytes = chunk_bytes;
      std::vector<Sent> sent;
      {
        McapWriter w(path.string(), o);
        const auto schema = w.add_schema("test.Blob", "jsonschema", R"({"type":"object"})");
        const std::vector<uint16_t> channels = {w.add_channel("/a", schema, "json"),
                                                w.add_channel("/b", schema, "json"),
                                                w.add_channel("/c", 0, "raw", {{"k", "v"}})};
        std::mt19937 rng(7);
        for (int i = 0; i < 200; ++i) {
          Sent s;
          s.channel = channels[rng() % 3];
          s.time = 1'700'000'000'000'000'000ull + static_cast<uint64_t>(i) * 1000 + rng() % 500;
          s.data.resize(rng() % 300);
          for (auto& b : s.data) b = static_cast<uint8_t>(rng());
          ASSERT_TRUE(w.write(s.channel, s.time, s.time + 1, s.data));
          sent.push_back(std::move(s));
        }
        w.close();
        EXPECT_EQ(w.stats().messages, 200u);
        EXPECT_EQ(w.stats().bytes, fs::file_size(path));
        if (chunk_bytes == 1) {
          EXPECT_EQ(w.stats().chunks, 200u);  // one per message, the first with the schema
        }
      }
      const auto check = lidartag::testing::check_mcap(path.string());
      EXPECT_TRUE(check.ok);
      EXPECT_EQ(check.messages, 200u);
      EXPECT_EQ(check.channels, 3u);
      EXPECT_EQ(check.schemas, 1u);

      auto reader = open_bag(path.string());
      ASSERT_EQ(reader->connections().size(), 3u);
      EXPECT_EQ(reader->connections()[0].topic, "/a");
      EXPECT_EQ(reader->connections()[0].type, "test.Blob");
      EXPECT_EQ(reader->connections()[2].type, "");
      uint64_t declared = 0;
      for (const auto& c : reader->connections()) declared += c.count;
      EXPECT_EQ(declared, 200u) << "counts from the Statistics record";
      BagMessage m;
      size_t i = 0;
      while (reader->next(m)) {
        ASSERT_LT(i, sent.size());
        EXPECT_EQ(m.connection, sent[i].channel);
        EXPECT_EQ(static_cast<uint64_t>(m.time_ns), sent[i].time);
        EXPECT_EQ(std::vector<uint8_t>(m.data.begin(), m.data.end()), sent[i].data) << i;
        ++i;
      }
      EXPECT_EQ(i, sent.size());
      EXPECT_TRUE(reader->error().empty()) << reader->error();
      fs::remove(path);
    }
  }
}

TEST(McapWriter, AFileWithoutMessagesIsComplete) {
  const auto path = temp_file("empty.mcap");
  {
    McapWriter w(path.string());
    w.add_channel("/nothing", 0, "json");
  }  // the destructor closes
  const auto check = lidartag::testing::check_mcap(path.string());
  EXPECT_TRUE(check.ok);
  EXPECT_EQ(check.messages, 0u);
  EXPECT_EQ(check.channels, 1u);
  fs::remove(path);
}

TEST(McapWriter, CloseKeepsEveryMessageOfTheOpenChunk) {
  const auto path = temp_file("close.mcap");
  McapWriterOptions o;
  o.chunk_bytes = 1u << 30;  // nothing written out before close()
  McapWriter w(path.string(), o);
  const auto ch = w.add_channel("/x", 0, "raw");
  for (uint64_t t = 1; t <= 1000; ++t) ASSERT_TRUE(w.write(ch, t, "message"));
  EXPECT_EQ(w.stats().chunks, 0u);
  w.close();
  w.close();  // a second close does nothing
  EXPECT_EQ(w.stats().chunks, 1u);
  EXPECT_EQ(lidartag::testing::check_mcap(path.string()).per_channel[ch], 1000u);
  fs::remove(path);
}

TEST(McapWriter, RefusesSpecialFilesUnknownChannelsAndWritesAfterClose) {
  const auto dir = temp_file("dir");
  fs::create_directories(dir);
  EXPECT_THROW(McapWriter(dir.string()), McapWriteError);
  const auto fifo = temp_file("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW(McapWriter(fifo.string()), McapWriteError);
  EXPECT_THROW(McapWriter((dir / "missing" / "x.mcap").string()), McapWriteError);
  EXPECT_THROW(parse_mcap_compression("bz2"), McapWriteError);
  fs::remove(fifo);

  const auto path = dir / "ok.mcap";
  McapWriter w(path.string());
  EXPECT_THROW(w.add_channel("/x", 5, "json"), McapWriteError);  // no schema 5
  const auto ch = w.add_channel("/x", 0, "json");
  EXPECT_FALSE(w.write(ch + 1, 1, "{}"));
  EXPECT_EQ(w.stats().failed_messages, 1u);
  EXPECT_TRUE(w.write(ch, 1, "{}")) << "an unknown channel does not spoil the file";
  w.close();
  EXPECT_FALSE(w.write(ch, 2, "{}"));
  EXPECT_THROW(w.add_schema("s", "jsonschema", "{}"), McapWriteError);
  EXPECT_EQ(lidartag::testing::check_mcap(path.string()).messages, 1u);
  fs::remove_all(dir);
}

TEST(McapWriter, Base64IsRfc4648) {
  const std::string in = "foobar";
  for (size_t n = 0; n <= in.size(); ++n) {
    std::string out;
    foxglove::append_base64({reinterpret_cast<const uint8_t*>(in.data()), n}, out);
    const char* expected[] = {"", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy"};
    EXPECT_EQ(out, expected[n]);
  }
}

}  // namespace
}  // namespace lidartag::driver::bag
