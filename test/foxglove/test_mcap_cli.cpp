// `lidartag detect --mcap` and `lidartag dump --format mcap` on the bundled demo capture (written
// by the simulator), run as a user would: the file passes the MCAP invariants and, read back with
// the project's MCAP reader, holds every rotation's cloud (its point count), its tags (one scene
// entity and one frame per detection, at detect --json's poses) and detect --json's object.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "foxglove/mcap_check.hpp"
#include "lidartag/driver/bag/message_reader.hpp"
#include "tools/run_tool.hpp"

namespace lidartag::driver::bag {
namespace {

namespace fs = std::filesystem;
using lidartag::testing::run_tool;
using nlohmann::json;

const std::string kDemo = LIDARTAG_SOURCE_DIR "/pcaps/demo.pcap";
const std::string kTags = " --tag-size 0.8 --tag-size 0.6";

fs::path temp_file(const std::string& name) {
  return fs::temp_directory_path() / ("lidartag_mcap_cli_" + std::to_string(::getpid()) + name);
}

std::vector<uint8_t> base64_decode(const std::string& s) {
  std::vector<uint8_t> out;
  uint32_t acc = 0;
  int bits = 0;
  for (const char c : s) {
    int v = -1;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    if (c >= '0' && c <= '9') v = c - '0' + 52;
    if (c == '+') v = 62;
    if (c == '/') v = 63;
    if (v < 0) continue;  // padding
    acc = (acc << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<uint8_t>((acc >> bits) & 0xFF));
    }
  }
  return out;
}

struct Read {
  std::map<std::string, std::vector<std::pair<int64_t, std::string>>> by_topic;
  std::map<std::string, std::string> types;
};

Read read_back(const fs::path& path) {
  Read r;
  auto reader = open_bag(path.string());
  BagMessage m;
  while (reader->next(m)) {
    const auto& c = reader->connections()[m.connection];
    r.by_topic[c.topic].emplace_back(m.time_ns, std::string(m.data.begin(), m.data.end()));
    r.types[c.topic] = c.type;
  }
  EXPECT_TRUE(reader->error().empty()) << reader->error();
  return r;
}

std::vector<json> json_lines(const std::string& out) {
  std::vector<json> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) lines.push_back(json::parse(line));
  return lines;
}

// Each foxglove.PointCloud message holds the points of the rotation `detect --json` printed at
// its place (18 bytes a point: x, y, z float32, intensity float32, ring uint16).
void expect_clouds_hold_the_rotations(const std::vector<std::pair<int64_t, std::string>>& clouds,
                                      const std::vector<json>& rotations) {
  ASSERT_EQ(clouds.size(), rotations.size());
  for (size_t i = 0; i < clouds.size(); ++i) {
    const json cloud = json::parse(clouds[i].second);
    EXPECT_EQ(base64_decode(cloud["data"].get<std::string>()).size(),
              rotations[i]["points"].get<size_t>() * 18)
        << "cloud " << i;
  }
}

int64_t stamp_ns(const json& time) {
  return time["sec"].get<int64_t>() * 1000000000 + time["nsec"].get<int64_t>();
}

TEST(McapCli, DetectWritesEveryRotationCloudTagsAndTheJsonPoses) {
  for (const std::string compression : {"zstd", "lz4", "none"}) {
    SCOPED_TRACE(compression);
    const auto path = temp_file("detect.mcap");
    const auto plain = run_tool("detect " + kDemo + kTags + " --json", false);
    ASSERT_EQ(plain.exit_code, 0) << plain.out;
    const auto with = run_tool("detect " + kDemo + kTags + " --json --mcap " + path.string() +
                                   " --mcap-compression " + compression,
                               false);
    ASSERT_EQ(with.exit_code, 0) << with.out;
    // --mcap changes nothing that detect prints (but the timings).
    const auto rotations = json_lines(with.out);
    auto untimed = [](std::vector<json> lines) {
      for (auto& l : lines) l.erase("timing_ms");
      return lines;
    };
    EXPECT_EQ(untimed(rotations), untimed(json_lines(plain.out)));
    ASSERT_GE(rotations.size(), 5u);

    const auto check = lidartag::testing::check_mcap(path.string());
    EXPECT_TRUE(check.ok);
    const Read r = read_back(path);
    EXPECT_EQ(r.types.at("/lidartag/cloud"), "foxglove.PointCloud");
    EXPECT_EQ(r.types.at("/lidartag/tags"), "foxglove.SceneUpdate");
    EXPECT_EQ(r.types.at("/tf"), "foxglove.FrameTransforms");
    EXPECT_EQ(r.types.at("/lidartag/detections"), "lidartag.Detections");
    const auto& clouds = r.by_topic.at("/lidartag/cloud");
    const auto& tags = r.by_topic.at("/lidartag/tags");
    const auto& dets = r.by_topic.at("/lidartag/detections");
    ASSERT_EQ(clouds.size(), rotations.size());
    ASSERT_EQ(tags.size(), rotations.size());
    ASSERT_EQ(dets.size(), rotations.size());
    size_t with_tags = 0, detections = 0;
    for (const auto& rot : rotations) {
      with_tags += rot["detections"].empty() ? 0u : 1u;
      detections += rot["detections"].size();
    }
    ASSERT_GT(detections, 0u);
    const auto& tf = r.by_topic.at("/tf");
    ASSERT_EQ(tf.size(), with_tags);

    size_t next_tf = 0;
    for (size_t i = 0; i < rotations.size(); ++i) {
      SCOPED_TRACE("rotation " + std::to_string(i));
      const json& rot = rotations[i];
      const auto stamp = static_cast<int64_t>(std::llround(rot["stamp"].get<double>() * 1e9));
      // Log times are the capture's (microsecond pcap stamps: the double holds them exactly).
      EXPECT_NEAR(static_cast<double>(clouds[i].first), static_cast<double>(stamp), 1e3);
      EXPECT_EQ(dets[i].first, clouds[i].first);
      EXPECT_EQ(json::parse(dets[i].second), rot) << "the detections message is --json's object";

      const json cloud = json::parse(clouds[i].second);
      EXPECT_EQ(stamp_ns(cloud["timestamp"]), clouds[i].first);
      EXPECT_EQ(cloud["point_stride"], 18);
      ASSERT_EQ(cloud["fields"].size(), 5u);
      EXPECT_EQ(cloud["fields"][4]["name"], "ring");
      const auto data = base64_decode(cloud["data"].get<std::string>());
      EXPECT_EQ(data.size(), rot["points"].get<size_t>() * 18) << "every point of the rotation";

      const json scene = json::parse(tags[i].second);
      EXPECT_EQ(scene["deletions"][0]["type"], 1);
      ASSERT_EQ(scene["entities"].size(), rot["detections"].size());
      if (rot["detections"].empty()) continue;
      ASSERT_LT(next_tf, tf.size());
      EXPECT_EQ(tf[next_tf].first, clouds[i].first);
      const json frames = json::parse(tf[next_tf++].second)["transforms"];
      ASSERT_EQ(frames.size(), rot["detections"].size());
      for (size_t k = 0; k < frames.size(); ++k) {
        const json& d = rot["detections"][k];
        const std::string name =
            "tag_" + d["family"].get<std::string>() + "_" + std::to_string(d["id"].get<int>());
        EXPECT_EQ(frames[k]["child_frame_id"], name);
        EXPECT_EQ(frames[k]["parent_frame_id"], "lidar");
        EXPECT_EQ(scene["entities"][k]["id"], name);
        const json& t = frames[k]["translation"];
        const json& q = frames[k]["rotation"];
        EXPECT_EQ(t["x"].get<double>(), d["position"][0].get<double>());
        EXPECT_EQ(t["y"].get<double>(), d["position"][1].get<double>());
        EXPECT_EQ(t["z"].get<double>(), d["position"][2].get<double>());
        EXPECT_EQ(q["w"].get<double>(), d["orientation"][0].get<double>());
        EXPECT_EQ(q["x"].get<double>(), d["orientation"][1].get<double>());
        EXPECT_EQ(q["y"].get<double>(), d["orientation"][2].get<double>());
        EXPECT_EQ(q["z"].get<double>(), d["orientation"][3].get<double>());
        const json& cube = scene["entities"][k]["cubes"][0];
        EXPECT_EQ(cube["pose"]["position"], json({{"x", t["x"]}, {"y", t["y"]}, {"z", t["z"]}}));
        EXPECT_EQ(cube["size"]["y"].get<double>(), d["size_m"].get<double>());
        EXPECT_EQ(scene["entities"][k]["texts"][0]["text"],
                  d["family"].get<std::string>() + " " + std::to_string(d["id"].get<int>()));
      }
    }
    fs::remove(path);
  }
}

TEST(McapCli, DumpFormatMcapWritesEveryRotationsCloud) {
  const auto path = temp_file("dump.mcap");
  fs::remove(path);
  const auto rotations = json_lines(run_tool("detect " + kDemo + " --json", false).out);
  const auto r = run_tool("dump " + kDemo + " --format mcap --out " + path.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(lidartag::testing::check_mcap(path.string()).ok);
  const Read back = read_back(path);
  EXPECT_EQ(back.by_topic.count("/lidartag/tags"), 0u) << "a conversion detects nothing";
  const auto& clouds = back.by_topic.at("/lidartag/cloud");
  expect_clouds_hold_the_rotations(clouds, rotations);
  // An existing output is replaced only with --force; the capture itself never.
  EXPECT_NE(run_tool("dump " + kDemo + " --format mcap --out " + path.string()).exit_code, 0);
  EXPECT_EQ(run_tool("dump " + kDemo + " --format mcap --force --out " + path.string()).exit_code,
            0);
  EXPECT_NE(run_tool("detect " + kDemo + " --mcap " + kDemo).exit_code, 0);
  EXPECT_TRUE(fs::file_size(kDemo) > 0);
  fs::remove(path);
}

// `dump --format mcap` of a bag's PointCloud2 topic (a real Luminar bag, five clouds): each cloud
// as a rotation's, with the points detect finds in it; --start/--duration choose the clouds.
TEST(McapCli, DumpFormatMcapOfAPointCloud2Topic) {
  const std::string luminar =
      std::string(LIDARTAG_SHARED_DIR) + "/captures/bags/ros1/luminar_pointcloud2_lz4.bag";
  if (!fs::exists(luminar)) GTEST_SKIP() << luminar << " not found (../shared/captures)";
  const auto path = temp_file("clouds.mcap");
  fs::remove(path);
  const auto rotations = json_lines(run_tool("detect " + luminar + " --json", false).out);
  ASSERT_EQ(rotations.size(), 5u);
  auto r = run_tool("dump " + luminar + " --format mcap --out " + path.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote 5 clouds to"), std::string::npos) << r.out;
  EXPECT_TRUE(lidartag::testing::check_mcap(path.string()).ok);
  const Read back = read_back(path);
  EXPECT_EQ(back.by_topic.count("/lidartag/tags"), 0u) << "a conversion detects nothing";
  ASSERT_EQ(back.by_topic.count("/lidartag/cloud"), 1u);
  const auto& clouds = back.by_topic.at("/lidartag/cloud");
  expect_clouds_hold_the_rotations(clouds, rotations);
  // The clouds 0.1 s apart: [0.15 s, 0.35 s) holds the third and fourth; --force replaces.
  EXPECT_NE(run_tool("dump " + luminar + " --format mcap --out " + path.string()).exit_code, 0);
  r = run_tool("dump --start 0.15 --duration 0.2 --force " + luminar + " --format mcap --out " +
               path.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const Read cut = read_back(path);
  ASSERT_EQ(cut.by_topic.count("/lidartag/cloud"), 1u);
  const auto& window = cut.by_topic.at("/lidartag/cloud");
  ASSERT_EQ(window.size(), 2u);
  EXPECT_EQ(json::parse(window[0].second)["data"], json::parse(clouds[2].second)["data"]);
  fs::remove(path);
}

#ifdef LIDARTAGD
// lidartagd --mcap on a replay of the demo capture: every published rotation's cloud (every point:
// lcm.cloud_decimation 1), tags, frames and detections, and the statuses, at the poses and point
// counts that `lidartag detect` with the same configuration finds.
TEST(McapDaemon, ReplayWritesEveryPublishedRotationAndTheStatus) {
  const auto path = temp_file("daemon.mcap");
  const std::string config = LIDARTAG_SOURCE_DIR "/config/demo.yaml";
  const auto daemon = lidartag::testing::run_split(
      std::string(LIDARTAGD) + " --config " + config + " --replay " + kDemo +
      " --max-speed --lcm-url memq:// --print-detections --set lcm.cloud_decimation=1 --mcap " +
      path.string());
  ASSERT_EQ(daemon.exit_code, 0) << daemon.err;
  const auto detect = run_tool("detect " + kDemo + " --partial --json --config " + config, false);
  ASSERT_EQ(detect.exit_code, 0);
  const auto rotations = json_lines(detect.out);
  size_t printed = 0;
  {
    std::istringstream in(daemon.out);
    for (std::string line; std::getline(in, line);) printed += line.rfind("demo rotation", 0) == 0;
  }
  ASSERT_EQ(printed, rotations.size()) << daemon.out;

  EXPECT_TRUE(lidartag::testing::check_mcap(path.string()).ok);
  const Read r = read_back(path);
  const auto& clouds = r.by_topic.at("/lidartag/demo/cloud");
  const auto& tags = r.by_topic.at("/lidartag/demo/tags");
  const auto& dets = r.by_topic.at("/lidartag/demo/detections");
  const auto& status = r.by_topic.at("/lidartag/demo/status");
  ASSERT_EQ(clouds.size(), rotations.size());
  ASSERT_EQ(tags.size(), rotations.size());
  ASSERT_EQ(dets.size(), rotations.size());
  ASSERT_GE(status.size(), 1u);
  const json final_status = json::parse(status.back().second);
  EXPECT_EQ(final_status["rotations_published"].get<size_t>(), rotations.size());
  EXPECT_EQ(final_status["sensor"], "demo");
  EXPECT_EQ(status.back().first, clouds.back().first) << "a status at the capture's time";

  size_t with_tags = 0;
  for (size_t i = 0; i < rotations.size(); ++i) {
    SCOPED_TRACE("rotation " + std::to_string(i));
    const json& rot = rotations[i];
    const json cloud = json::parse(clouds[i].second);
    EXPECT_EQ(cloud["frame_id"], "velodyne");
    EXPECT_EQ(base64_decode(cloud["data"].get<std::string>()).size(),
              rot["points"].get<size_t>() * 18);
    const json d = json::parse(dets[i].second);
    EXPECT_EQ(d["sequence"], rot["sequence"]);
    EXPECT_EQ(dets[i].first, clouds[i].first);
    ASSERT_EQ(d["detections"].size(), rot["detections"].size());
    EXPECT_EQ(json::parse(tags[i].second)["entities"].size(), rot["detections"].size());
    with_tags += rot["detections"].empty() ? 0u : 1u;
    for (size_t k = 0; k < d["detections"].size(); ++k) {
      const json& a = d["detections"][k];
      const json& b = rot["detections"][k];
      EXPECT_EQ(a["family"], b["family"]);
      EXPECT_EQ(a["id"], b["id"]);
      for (size_t c = 0; c < 3; ++c)
        EXPECT_NEAR(a["position"][c].get<double>(), b["position"][c].get<double>(), 1e-9);
      for (size_t c = 0; c < 4; ++c)
        EXPECT_NEAR(a["orientation"][c].get<double>(), b["orientation"][c].get<double>(), 1e-9);
    }
  }
  EXPECT_GT(with_tags, 0u);
  EXPECT_EQ(r.by_topic.at("/tf").size(), with_tags);

  // The output is checked before anything starts: the replayed capture is refused.
  EXPECT_NE(
      lidartag::testing::run_split(std::string(LIDARTAGD) + " --config " + config + " --replay " +
                                   kDemo + " --max-speed --lcm-url memq:// " + "--mcap " + kDemo)
          .exit_code,
      0);
  fs::remove(path);
}
#endif

}  // namespace
}  // namespace lidartag::driver::bag
