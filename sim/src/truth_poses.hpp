// Shared by the Velodyne and Ouster runs: each rotation's sensor pose and tags in its frame.
#pragma once

#include <cstdint>
#include <vector>

#include "lidartag/sim/sensor_sim.hpp"
#include "lidartag/sim/tag_target.hpp"
#include "lidartag/sim/truth.hpp"

namespace lidartag::sim {

// Fills every rotation's sensor pose (at its stamp_ns, the trajectory starting at `start_ns`) and
// its tags' poses and corners in that sensor frame (rt.tags already sized, returns counted).
void fill_truth_poses(Truth& truth, const Trajectory& trajectory,
                      const std::vector<TagTarget>& tags, int64_t start_ns);

}  // namespace lidartag::sim
