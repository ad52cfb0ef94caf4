// Seeded random clutter: indoor lab furniture and people, outdoor trees/poles/bushes, or a
// parking lot of cars in rows. Objects never cover the keep-out zones (sensor, tags and the lines
// of sight to them), so clutter never hides a tag.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

// A capsule on the ground plane: every point within `radius` of the segment a-b (x, y, metres).
struct KeepOut {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double radius = 0.0;
};

struct Clutter {
  std::vector<BoxOptions> boxes;
  std::vector<CylinderOptions> cylinders;
};

// Same options and keep-outs, same objects, on every platform (own distributions over
// std::mt19937_64). Places up to options.count objects; fewer when the region is too full.
Clutter generate_clutter(const ClutterOptions& options, std::span<const KeepOut> keep_out);

}  // namespace lidartag::sim
