// Scene YAML: defaults, every section mapped, and typed errors naming the bad key.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim {
namespace {

std::string error_of(const std::string& yaml) {
  try {
    parse_scene(yaml, "test.yaml");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(SceneYaml, EmptySensorGivesDocumentedDefaults) {
  const Scene s = parse_scene("sensor: {}\n");
  EXPECT_EQ(s.sensor.model, velodyne::Model::kVLP32C);
  EXPECT_EQ(s.sensor.rpm, 600.0);
  EXPECT_EQ(s.sensor.return_mode, velodyne::ReturnMode::kStrongest);
  EXPECT_EQ(s.sensor.height, 1.0);
  EXPECT_EQ(s.sensor.cut_azimuth_deg, 180.0);
  EXPECT_DOUBLE_EQ(s.sensor.noise.range_sigma_m, 0.015);
  EXPECT_TRUE(s.world.ground);
  EXPECT_FALSE(s.world.room.enabled);
  EXPECT_FALSE(s.world.clutter.enabled);
  EXPECT_TRUE(s.tags.empty());
  EXPECT_EQ(s.seed, 1u);
  EXPECT_EQ(s.rotations, 10);
}

TEST(SceneYaml, PerModelNoiseDefaults) {
  EXPECT_DOUBLE_EQ(parse_scene("sensor: {model: hdl32e}").sensor.noise.range_sigma_m, 0.02);
  EXPECT_DOUBLE_EQ(parse_scene("sensor: {model: vlp16}").sensor.noise.range_sigma_m, 0.015);
  const Scene s = parse_scene("sensor: {model: vls128, noise: {range_sigma_m: 0.03}}");
  EXPECT_DOUBLE_EQ(s.sensor.noise.range_sigma_m, 0.03);
  EXPECT_EQ(s.sensor.noise.footprint_samples, 5);  // the rest keeps its defaults
  const Scene ideal = parse_scene("sensor: {noise: none}");
  EXPECT_EQ(ideal.sensor.noise.range_sigma_m, 0.0);
  EXPECT_EQ(ideal.sensor.noise.footprint_samples, 1);
  EXPECT_EQ(ideal.sensor.noise.dropout, 0.0);
}

TEST(SceneYaml, FullSceneMapsEveryKey) {
  const Scene s = parse_scene(R"(
seed: 42
rotations: 3
sensor:
  model: vlp16
  rpm: 900
  return_mode: dual
  position: [1, 2]
  height: 1.5
  roll_deg: 1
  pitch_deg: 2
  yaw_deg: 30
  velocity: [1, 0, 0]
  angular_velocity: [0, 0, 10]
  start_time_s: 1600000000.5
  cut_azimuth_deg: 90
  position_packets: true
  position_rate_hz: 50
world:
  ground: false
  ground_reflectivity: 25
  room: {center: [1, 1], size: [12, 9], height: 4, yaw_deg: 5, reflectivity: 45, ceiling: false}
  walls: [{from: [0, 5], to: [5, 5], height: 2, thickness: 0.2, reflectivity: 33}]
  boxes: [{center: [4, -2, 0.5], size: [1, 2, 1], yaw_deg: 10, reflectivity: 20}]
  cylinders: [{base: [3, 3, 0], radius: 0.1, height: 2, reflectivity: 40}]
  clutter: {kind: parking, seed: 7, count: 12, region: [-20, 20, -15, 15], clearance: 1}
tags:
  - family: tag25h9
    id: 3
    size: 0.6
    center: [4, 0, 1.2]
    normal: [-1, 0, 0]
    rotation: square
    board: {thickness: 0.03, margin: 0.1, reflectivity: 55}
    stand: {width: 0.04, reflectivity: 20}
    retro_reflective: true
    black_reflectivity: 4
  - {size: 1.2, center: [6, 2, 1], rotation: 30, stand: true}
)");
  EXPECT_EQ(s.seed, 42u);
  EXPECT_EQ(s.rotations, 3);
  EXPECT_EQ(s.sensor.model, velodyne::Model::kVLP16);
  EXPECT_EQ(s.sensor.rpm, 900.0);
  EXPECT_EQ(s.sensor.return_mode, velodyne::ReturnMode::kDual);
  EXPECT_EQ(s.sensor.position[1], 2.0);
  EXPECT_EQ(s.sensor.yaw_deg, 30.0);
  EXPECT_EQ(s.sensor.angular_velocity[2], 10.0);
  EXPECT_EQ(s.sensor.start_time_s, 1600000000.5);
  EXPECT_EQ(s.sensor.cut_azimuth_deg, 90.0);
  EXPECT_TRUE(s.sensor.position_packets);
  EXPECT_EQ(s.sensor.position_rate_hz, 50.0);
  EXPECT_FALSE(s.world.ground);
  EXPECT_TRUE(s.world.room.enabled);
  EXPECT_FALSE(s.world.room.ceiling);
  EXPECT_EQ(s.world.room.size[0], 12.0);
  ASSERT_EQ(s.world.walls.size(), 1u);
  EXPECT_EQ(s.world.walls[0].reflectivity, 33.0);
  ASSERT_EQ(s.world.boxes.size(), 1u);
  EXPECT_EQ(s.world.boxes[0].size[1], 2.0);
  ASSERT_EQ(s.world.cylinders.size(), 1u);
  EXPECT_EQ(s.world.cylinders[0].radius, 0.1);
  EXPECT_TRUE(s.world.clutter.enabled);
  EXPECT_EQ(s.world.clutter.kind, ClutterKind::kParking);
  EXPECT_EQ(s.world.clutter.seed, 7u);
  ASSERT_EQ(s.tags.size(), 2u);
  EXPECT_EQ(s.tags[0].family, "tag25h9");
  EXPECT_EQ(s.tags[0].id, 3);
  EXPECT_EQ(s.tags[0].rotation_deg, 0.0);
  EXPECT_EQ(s.tags[0].board.margin, 0.1);
  EXPECT_TRUE(s.tags[0].stand.enabled);
  EXPECT_EQ(s.tags[0].white_reflectivity, 200.0);
  EXPECT_EQ(s.tags[0].black_reflectivity, 4.0);
  EXPECT_EQ(s.tags[1].family, "tag16h5");
  EXPECT_EQ(s.tags[1].rotation_deg, 30.0);
  EXPECT_TRUE(s.tags[1].stand.enabled);
  EXPECT_EQ(s.tags[1].white_reflectivity, 80.0);
}

TEST(SceneYaml, UnknownKeysAreRejectedByPath) {
  EXPECT_NE(error_of("sensr: {}").find("sensr: unknown key"), std::string::npos);
  EXPECT_NE(error_of("sensor: {rmp: 600}").find("sensor.rmp: unknown key"), std::string::npos);
  EXPECT_NE(error_of("sensor: {noise: {sigma: 1}}").find("sensor.noise.sigma"), std::string::npos);
  EXPECT_NE(error_of("tags: [{size: 1, center: [1,0,1]}, {size: 1, center: [2,0,1], colour: 3}]")
                .find("tags[1].colour: unknown key"),
            std::string::npos);
  EXPECT_NE(error_of("world: {room: {heigth: 3}}").find("world.room.heigth"), std::string::npos);
}

TEST(SceneYaml, BadValuesNameTheKey) {
  EXPECT_NE(error_of("sensor: {model: vlp64}").find("sensor.model: unknown model 'vlp64'"),
            std::string::npos);
  EXPECT_NE(error_of("sensor: {rpm: 100}").find("sensor.rpm"), std::string::npos);
  EXPECT_NE(error_of("sensor: {rpm: fast}").find("sensor.rpm: expected a number"),
            std::string::npos);
  EXPECT_NE(error_of("sensor: {return_mode: first}").find("sensor.return_mode"), std::string::npos);
  EXPECT_NE(error_of("sensor: {noise: {dropout: 1.5}}").find("sensor.noise.dropout"),
            std::string::npos);
  EXPECT_NE(error_of("sensor: {noise: {footprint_samples: 4}}").find("footprint_samples"),
            std::string::npos);
  EXPECT_NE(error_of("sensor: {position: [1, 2, 3]}").find("sensor.position: expected a list of 2"),
            std::string::npos);
  EXPECT_NE(error_of("tags: [{center: [1, 0, 1]}]").find("tags[0]: needs 'size'"),
            std::string::npos);
  EXPECT_NE(error_of("tags: [{size: -1, center: [1, 0, 1]}]").find("tags[0].size"),
            std::string::npos);
  EXPECT_NE(error_of("world: {clutter: {kind: forest}}").find("world.clutter.kind"),
            std::string::npos);
  EXPECT_NE(error_of("seed: -3").find("seed: expected a non-negative"), std::string::npos);
  EXPECT_NE(error_of("sensor: [1, 2]").find("sensor: expected a mapping"), std::string::npos);
  EXPECT_NE(error_of("sensor: {rpm: [600").find("invalid YAML"), std::string::npos);
  // Every message starts with the source name.
  EXPECT_EQ(error_of("sensor: {rpm: 100}").rfind("test.yaml: ", 0), 0u);
}

TEST(SceneYaml, FamilyAndIdAreCheckedWhenTheSimulatorIsBuilt) {
  auto build_error = [](const std::string& yaml) -> std::string {
    try {
      Simulator sim(parse_scene(yaml));
    } catch (const SceneError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(
      build_error("tags: [{family: tag99h1, size: 1, center: [3, 0, 1]}]").find("tags[0].family"),
      std::string::npos);
  EXPECT_NE(build_error("tags: [{family: tag16h5, id: 30, size: 1, center: [3, 0, 1]}]")
                .find("tags[0].id: 30 is not a code of tag16h5"),
            std::string::npos);
  EXPECT_EQ(build_error("tags: [{family: tag36h11, id: 586, size: 1, center: [3, 0, 1]}]"), "");
}

TEST(SceneYaml, LoadSceneReadsFilesAndReportsMissingOnes) {
  EXPECT_THROW(load_scene("/nonexistent/scene.yaml"), SceneError);
  const std::string path =
      ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_sim_scene_test.yaml";
  {
    std::ofstream out(path);
    out << "sensor: {model: hdl32e}\nrotations: 2\n";
  }
  const Scene s = load_scene(path);
  EXPECT_EQ(s.sensor.model, velodyne::Model::kHDL32E);
  EXPECT_EQ(s.rotations, 2);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace lidartag::sim
