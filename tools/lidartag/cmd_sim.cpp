// `lidartag sim SCENE.yaml --out FILE.pcap --truth FILE.json [--image FILE.png] [--rotations N]
// [--seed S]`: writes the capture a real Velodyne would record of the scene, its ground truth and,
// with a `camera:` section, the camera's image (docs/simulator.md, docs/camera.md). A scene with a
// `series:` of tag poses writes one capture, truth and image per pose, numbered FILE_00.pcap, ...
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "lidartag/calib/image_io.hpp"
#include "lidartag/commands.hpp"
#include "lidartag/driver/io/pcap_writer.hpp"
#include "lidartag/progress.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::cli {
namespace {

struct SimArgs {
  std::string scene;
  std::string out;
  std::string truth;
  std::string image;
  std::optional<int> rotations;
  std::optional<uint64_t> seed;
};

// PATH with `_NN` before its extension (series pose `index` of `count`); PATH itself for a single
// capture.
std::string numbered(const std::string& path, size_t index, size_t count) {
  if (count == 0 || path.empty()) return path;
  const std::filesystem::path p(path);
  const int digits = std::max(2, static_cast<int>(std::to_string(count - 1).size()));
  return (p.parent_path() /
          (p.stem().string() + fmt::format("_{:0{}}", index, digits) + p.extension().string()))
      .string();
}

int run_one(const SimArgs& args, sim::Scene scene, uint64_t seed);

int run_sim(const SimArgs& args) {
  const sim::Scene scene = sim::load_scene(args.scene);
  if (!args.image.empty() && !scene.camera)
    throw sim::SceneError(args.scene + ": --image needs a camera: section in the scene");
  const uint64_t seed = args.seed.value_or(scene.seed);
  if (scene.series.empty()) return run_one(args, scene, seed);
  // A calibration series: pose i with seed + i, each its own numbered files.
  for (size_t i = 0; i < scene.series.size(); ++i) {
    SimArgs a = args;
    a.out = numbered(args.out, i, scene.series.size());
    a.truth = numbered(args.truth, i, scene.series.size());
    a.image = numbered(args.image, i, scene.series.size());
    fmt::print("series pose {} of {}\n", i + 1, scene.series.size());
    const int rc = run_one(a, sim::series_scene(scene, i), seed + i);
    if (rc != 0) return rc;
  }
  return 0;
}

int run_one(const SimArgs& args, sim::Scene scene, uint64_t seed) {
  const int rotations = args.rotations.value_or(scene.rotations);
  // With a camera and no --image, the image goes beside the capture.
  std::string image = args.image;
  if (scene.camera && image.empty())
    image = std::filesystem::path(args.out).replace_extension(".png").string();
  sim::Simulator simulator(std::move(scene));
  driver::PcapWriter writer(args.out);
  sim::RunStats stats;
  // Progress by the packets' time: `rotations` periods from the scene's start time.
  const auto& so = simulator.scene().sensor;
  const double period_ns = 60e9 / so.rpm;
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
  if (!image.empty() && !truth.rotations.empty())
    calib::write_png(simulator.render_image(truth.rotations.front(), seed), image);

  const auto& sensor = simulator.scene().sensor;
  fmt::print("{}: {} {} rpm {}, {} rotations, seed {}\n", args.scene,
             velodyne::model_spec(sensor.model).display_name, sensor.rpm,
             velodyne::return_mode_name(sensor.return_mode), rotations, seed);
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
  if (!args.truth.empty()) fmt::print("wrote {}\n", args.truth);
  if (!image.empty()) {
    const auto& m = simulator.scene().camera->model;
    fmt::print("wrote {}: {}x{} camera image at rotation 0\n", image, m.width, m.height);
  }
  return 0;
}

const Registrar kSim("sim", "Simulate a scene: write a Velodyne pcap and its ground truth",
                     [](CLI::App& app) {
                       auto args = std::make_shared<SimArgs>();
                       app.add_option("scene", args->scene, "scene file (YAML)")
                           ->required()
                           ->check(CLI::ExistingFile);
                       app.add_option("--out", args->out, "pcap file to write")->required();
                       app.add_option("--truth", args->truth, "ground-truth JSON file to write");
                       app.add_option("--image", args->image,
                                      "camera image (PNG) to write; needs a camera: section "
                                      "(default: the --out path with .png)");
                       app.add_option("--rotations", args->rotations,
                                      "rotations to simulate (default: the scene's, else 10)")
                           ->check(CLI::Range(1, 100000));
                       app.add_option("--seed", args->seed,
                                      "noise seed (default: the scene's, else 1)");
                       return [args] { return run_sim(*args); };
                     });

}  // namespace
}  // namespace lidartag::cli
