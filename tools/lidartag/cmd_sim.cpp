// `lidartag sim SCENE.yaml --out FILE.pcap --truth FILE.json [--rotations N] [--seed S]`: writes
// the capture a real Velodyne or Ouster would record of the scene, and its ground truth
// (docs/simulator.md). An Ouster capture's metadata goes beside it: FILE.pcap -> FILE.json.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "lidartag/commands.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/exit_codes.hpp"
#include "lidartag/progress.hpp"
#include "lidartag/sim/ouster_sim.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::cli {
namespace {

struct SimArgs {
  std::string scene;
  std::string out;
  std::string truth;
  std::optional<int> rotations;
  std::optional<uint64_t> seed;
};

int run_sim(const SimArgs& args) {
  sim::Scene scene = sim::load_scene(args.scene);
  const int rotations = args.rotations.value_or(scene.rotations);
  const uint64_t seed = args.seed.value_or(scene.seed);
  // An Ouster capture is read with its metadata, NAME.json beside NAME.pcap.
  std::string metadata;
  if (scene.sensor.ouster) {
    metadata = std::filesystem::path(args.out).replace_extension(".json").string();
    if (metadata == args.out || (!args.truth.empty() && std::filesystem::path(args.truth) ==
                                                            std::filesystem::path(metadata)))
      throw UsageError("--truth: '" + metadata +
                       "' is where the Ouster capture's metadata goes: "
                       "name the truth file otherwise");
  }
  sim::Simulator simulator(std::move(scene));
  driver::PcapWriter writer(args.out);
  sim::RunStats stats;
  // Progress by the packets' time: `rotations` periods from the scene's start time.
  const auto& so = simulator.scene().sensor;
  const double period_ns = so.ouster ? 1e9 / so.ouster->rate_hz : 60e9 / so.rpm;
  const auto start_ns = static_cast<int64_t>(so.start_time_s * 1e9);
  Progress progress(static_cast<uint64_t>(period_ns * rotations));
  const sim::Truth truth = simulator.run(
      rotations, seed,
      [&](std::span<const uint8_t> payload, int64_t time_ns, uint16_t port) {
        writer.write_udp(payload, time_ns, port);
        if (progress.on() && time_ns > start_ns) {
          const auto done = static_cast<uint64_t>(time_ns - start_ns);
          progress.update(
              done, fmt::format("rotation {} of {}",
                                std::min<int64_t>(rotations, int64_t(double(done) / period_ns) + 1),
                                rotations));
        }
      },
      &stats);
  progress.done();
  writer.close();
  if (!args.truth.empty()) sim::write_truth(truth, args.truth);

  const auto& sensor = simulator.scene().sensor;
  if (sensor.ouster) {
    const auto info = sim::ouster_sensor_info(sensor);
    driver::ouster::write_metadata(info, metadata);
    fmt::print("{}: {} {}x{} {}, {} rotations, seed {}\n", args.scene, info.prod_line,
               info.mode_columns, info.mode_rate_hz, driver::ouster::profile_name(info.profile),
               rotations, seed);
  } else {
    fmt::print("{}: {} {} rpm {}, {} rotations, seed {}\n", args.scene,
               velodyne::model_spec(sensor.model).display_name, sensor.rpm,
               velodyne::return_mode_name(sensor.return_mode), rotations, seed);
  }
  fmt::print("wrote {}: {} data packets, {} position packets, {} points\n", args.out,
             stats.data_packets, stats.position_packets, stats.points);
  for (size_t i = 0; i < simulator.tags().size(); ++i) {
    const auto& tag = simulator.tags()[i];
    int64_t returns = 0;
    for (const auto& r : truth.rotations) returns += r.tags[i].returns;
    fmt::print("tag {} {} id {} size {} m: {:.1f} returns per rotation\n", i, tag.family_name,
               tag.options.id, tag.options.size,
               truth.rotations.empty()
                   ? 0.0
                   : static_cast<double>(returns) / static_cast<double>(truth.rotations.size()));
  }
  if (!metadata.empty()) fmt::print("wrote {} (the sensor's metadata)\n", metadata);
  if (!args.truth.empty()) fmt::print("wrote {}\n", args.truth);
  return 0;
}

const Registrar kSim("sim",
                     "Simulate a scene: write a Velodyne or Ouster pcap and its ground truth",
                     [](CLI::App& app) {
                       auto args = std::make_shared<SimArgs>();
                       app.add_option("scene", args->scene, "scene file (YAML)")
                           ->required()
                           ->check(CLI::ExistingFile);
                       app.add_option("--out", args->out, "pcap file to write")->required();
                       app.add_option("--truth", args->truth, "ground-truth JSON file to write");
                       app.add_option("--rotations", args->rotations,
                                      "rotations to simulate (default: the scene's, else 10)")
                           ->check(CLI::Range(1, 100000));
                       app.add_option("--seed", args->seed,
                                      "noise seed (default: the scene's, else 1)");
                       return [args] { return run_sim(*args); };
                     });

}  // namespace
}  // namespace lidartag::cli
