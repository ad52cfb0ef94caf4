// The MCAP writer: files of every compression and chunk size pass the format's invariants
// (mcap_check.hpp) and read back, message for message, through the project's MCAP reader.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
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

// A write error (here a file-size limit: EFBIG, as a full disk gives ENOSPC) makes write() return
// false and close() throw, never crash; in a child process, whose limit the test cannot leak.
TEST(McapWriter, AWriteErrorIsReportedByWriteAndClose) {
  const auto path = temp_file("limit.mcap");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{256 * 1024, 256 * 1024};
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 0;
    try {
      McapWriterOptions o;
      o.compression = McapCompression::kNone;
      o.chunk_bytes = 64 * 1024;
      McapWriter w(path.string(), o);
      const auto ch = w.add_channel("/x", 0, "raw");
      const std::string payload(10000, 'x');
      bool refused = false;
      for (uint64_t t = 0; t < 100 && !refused; ++t) refused = !w.write(ch, t, payload);
      code = refused && !w.error().empty() ? 0 : 2;
      try {
        w.close();
        code = 3;  // close() must not succeed on a file it could not complete
      } catch (const McapWriteError&) {
      }
    } catch (...) {
      code = 4;
    }
    std::_Exit(code);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "2: no refusal, 3: close succeeded, 4: other exception";
  fs::remove(path);
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

namespace lidartag::foxglove {
namespace {

TEST(SceneRecorder, EveryMessageIsJsonOfItsSchemaPerSensor) {
  namespace fs = std::filesystem;
  for (const char* name : {"foxglove.PointCloud", "foxglove.SceneUpdate",
                           "foxglove.FrameTransforms", "lidartag.Detections", "lidartag.Status"}) {
    const auto schema = nlohmann::json::parse(json_schema(name));  // throws when not JSON
    EXPECT_EQ(schema["title"], name);
  }
  const auto path = fs::temp_directory_path() / ("lidartag_scene_" + std::to_string(::getpid()));
  CloudPoints cloud;
  cloud.push(1.0f, -2.0f, 0.5f, 200.0f, 7);
  cloud.push(3.0f, 4.0f, -1.0f, 0.0f, 0);
  detector::Detection d;
  d.corners.fill(Eigen::Vector3d::Zero());
  d.family = "tag16h5";
  d.id = 3;
  d.size_m = 0.8;
  d.position = Eigen::Vector3d(4.0, 0.9, 0.1);
  d.orientation = Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5);
  const std::vector<detector::Detection> detections = {d};
  {
    SceneRecorder rec(path.string());
    RotationRecord r;
    r.sensor = "left";
    r.frame_id = "lidar \"left\"";  // escaped in every message
    r.sequence = 5;
    r.stamp_ns = 1'700'000'000'123'456'789;
    r.cloud = &cloud;
    r.detections = detections;
    ASSERT_TRUE(rec.write_rotation(r));
    r.sensor = "right";
    r.cloud = nullptr;  // no cloud message
    r.detections = {};
    r.stamp_ns += 100'000'000;
    ASSERT_TRUE(rec.write_rotation(r));
    ASSERT_TRUE(rec.write_status("right", r.stamp_ns, R"({"sensor":"right"})"));
    rec.close();
    EXPECT_EQ(rec.counts().clouds, 1u);
    EXPECT_EQ(rec.counts().scenes, 2u);
    EXPECT_EQ(rec.counts().transforms, 1u);
    EXPECT_EQ(rec.counts().statuses, 1u);
  }
  EXPECT_TRUE(lidartag::testing::check_mcap(path.string()).ok);
  auto reader = driver::bag::open_bag(path.string());
  std::map<std::string, std::vector<nlohmann::json>> by_topic;
  std::map<std::string, int64_t> first_time;
  driver::bag::BagMessage m;
  while (reader->next(m)) {
    const auto& c = reader->connections()[m.connection];
    by_topic[c.topic].push_back(nlohmann::json::parse(m.data.begin(), m.data.end()));
    first_time.emplace(c.topic, m.time_ns);
  }
  EXPECT_EQ(by_topic["/lidartag/left/cloud"].size(), 1u);
  EXPECT_EQ(by_topic.count("/lidartag/right/cloud"), 0u);
  EXPECT_EQ(by_topic["/lidartag/left/tags"].size(), 1u);
  EXPECT_EQ(by_topic["/lidartag/right/tags"].size(), 1u);
  EXPECT_EQ(by_topic["/tf"].size(), 1u);
  EXPECT_EQ(by_topic["/lidartag/right/status"].size(), 1u);
  EXPECT_EQ(first_time["/lidartag/left/cloud"], 1'700'000'000'123'456'789);

  const auto& pc = by_topic["/lidartag/left/cloud"][0];
  EXPECT_EQ(pc["frame_id"], "lidar \"left\"");
  EXPECT_EQ(pc["timestamp"]["sec"], 1'700'000'000);
  EXPECT_EQ(pc["timestamp"]["nsec"], 123'456'789);
  // The packed points: decode the base64 and read them back as Foxglove would.
  const std::string b64 = pc["data"];
  std::vector<uint8_t> bytes;
  uint32_t acc = 0;
  int bits = 0;
  const std::string digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  for (const char c : b64) {
    if (c == '=') break;
    acc = (acc << 6) | static_cast<uint32_t>(digits.find(c));
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      bytes.push_back(static_cast<uint8_t>(acc >> bits));
    }
  }
  ASSERT_EQ(bytes.size(), 2u * pc["point_stride"].get<size_t>());
  auto field = [&](size_t point, const std::string& fname) -> double {
    for (const auto& f : pc["fields"]) {
      if (f["name"] != fname) continue;
      const size_t at = point * pc["point_stride"].get<size_t>() + f["offset"].get<size_t>();
      if (f["type"] == 7) {
        float v = 0;
        std::memcpy(&v, bytes.data() + at, 4);
        return v;
      }
      if (f["type"] == 3) {
        uint16_t v = 0;
        std::memcpy(&v, bytes.data() + at, 2);
        return v;
      }
    }
    ADD_FAILURE() << "no field " << fname;
    return 0;
  };
  EXPECT_EQ(field(0, "x"), 1.0);
  EXPECT_EQ(field(0, "y"), -2.0);
  EXPECT_EQ(field(0, "z"), 0.5);
  EXPECT_EQ(field(0, "intensity"), 200.0);
  EXPECT_EQ(field(0, "ring"), 7.0);
  EXPECT_EQ(field(1, "y"), 4.0);

  const auto& left = by_topic["/lidartag/left/tags"][0];
  ASSERT_EQ(left["entities"].size(), 1u);
  EXPECT_EQ(left["entities"][0]["id"], "tag_tag16h5_3");
  EXPECT_EQ(left["entities"][0]["frame_id"], "lidar \"left\"");
  EXPECT_EQ(left["entities"][0]["cubes"][0]["pose"]["orientation"]["w"], 0.5);
  EXPECT_EQ(left["entities"][0]["texts"][0]["text"], "tag16h5 3");
  EXPECT_TRUE(by_topic["/lidartag/right/tags"][0]["entities"].empty());
  EXPECT_EQ(by_topic["/lidartag/right/tags"][0]["deletions"][0]["type"], 1);
  const auto& tf = by_topic["/tf"][0]["transforms"][0];
  EXPECT_EQ(tf["child_frame_id"], "tag_tag16h5_3");
  EXPECT_EQ(tf["translation"]["x"], 4.0);
  EXPECT_EQ(tf["rotation"]["y"], -0.5);
  const auto& det = by_topic["/lidartag/left/detections"][0];
  EXPECT_EQ(det["sensor"], "left");
  EXPECT_EQ(det["sequence"], 5);
  EXPECT_EQ(det["detections"][0]["position"], nlohmann::json({4.0, 0.9, 0.1}));
  EXPECT_EQ(det["detections"][0]["orientation"], nlohmann::json({0.5, 0.5, -0.5, 0.5}));
  fs::remove(path);
}

}  // namespace
}  // namespace lidartag::foxglove
