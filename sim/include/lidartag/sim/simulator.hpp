// The simulator: scene -> the packets a real sensor would send, handed to a callback, plus the
// ground truth. Steps: build the world (primitives, clutter, tag boards), then per column: pose,
// ray casting per laser and footprint ray, echoes and artefacts, return mode, noise, packets.
// Pure library: no files (the `lidartag sim` command writes the pcap and truth file).
#pragma once

#include <cstdint>
#include <vector>

#include "lidartag/calib/image_io.hpp"
#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/packetizer.hpp"
#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/tag_target.hpp"
#include "lidartag/sim/truth.hpp"

namespace lidartag::sim {

struct RunStats {
  uint64_t columns = 0;
  uint64_t data_packets = 0;
  uint64_t position_packets = 0;
  uint64_t points = 0;  // reported returns, all columns (dual copies of one echo counted once)
};

class Simulator {
 public:
  // Resolves families, places tags and clutter. Throws SceneError.
  explicit Simulator(Scene scene);

  // Simulates `rotations` whole rotations from the cut azimuth to the cut azimuth, with a short
  // lead-in (two packets) before the first cut and two packets after the last, so that a
  // batcher cutting at scene.sensor.cut_azimuth_deg delivers exactly `rotations` complete
  // rotations matching the truth. Same scene and seed: identical packets and truth.
  Truth run(int rotations, uint64_t seed, const PacketCallback& emit,
            RunStats* stats = nullptr) const;

  // The camera's image (scene.camera required) at the LiDAR pose of `rotation` (a rotation of
  // run()'s truth: its first firing). Noise from `seed`.
  calib::GrayImage render_image(const RotationTruth& rotation, uint64_t seed) const;

  const Scene& scene() const { return scene_; }
  const World& world() const { return world_; }
  const std::vector<TagTarget>& tags() const { return tags_; }

 private:
  Scene scene_;
  World world_;
  std::vector<TagTarget> tags_;
};

}  // namespace lidartag::sim
