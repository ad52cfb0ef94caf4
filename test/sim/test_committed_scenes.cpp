// The committed captures' scenes stay valid, and their truth files match their scenes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim {
namespace {

class CommittedScene : public ::testing::TestWithParam<const char*> {};

TEST_P(CommittedScene, SceneLoadsAndTruthMatchesIt) {
  const std::string base = std::string(LIDARTAG_SOURCE_DIR) + "/pcaps/" + GetParam();
  const Scene scene = load_scene(base + ".yaml");
  const Simulator sim(scene);  // families, ids and poses resolve
  std::ifstream in(base + ".truth.json");
  ASSERT_TRUE(in) << base << ".truth.json";
  const nlohmann::json truth = nlohmann::json::parse(in);
  EXPECT_EQ(truth["model"], velodyne::model_spec(scene.sensor.model).name);
  ASSERT_EQ(truth["rotations"].size(), static_cast<size_t>(scene.rotations));
  for (const auto& r : truth["rotations"]) {
    ASSERT_EQ(r["tags"].size(), scene.tags.size());
    for (size_t i = 0; i < scene.tags.size(); ++i) {
      EXPECT_EQ(r["tags"][i]["id"], scene.tags[i].id);
      EXPECT_EQ(r["tags"][i]["size"], scene.tags[i].size);
      EXPECT_GT(r["tags"][i]["returns"].get<int>(), 0) << "tag " << i << " is not seen";
    }
  }
  // Real Ethernet/IPv4/UDP records of 1206-byte payloads: 16 + 14 + 20 + 8 + 1206 bytes each,
  // after the 24-byte file header (position packets add records of another size); a few MB.
  const auto size = std::filesystem::file_size(base + ".pcap");
  if (!scene.sensor.position_packets) {
    EXPECT_EQ((size - 24) % (16 + 14 + 20 + 8 + 1206), 0u);
  }
  EXPECT_LT(size, 5u * 1024 * 1024);
}

INSTANTIATE_TEST_SUITE_P(Pcaps, CommittedScene,
                         ::testing::Values("demo", "outdoor", "clutter", "boards"));

}  // namespace
}  // namespace lidartag::sim
