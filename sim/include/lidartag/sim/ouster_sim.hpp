// Ouster sensors in the simulator: every column fires all its beams at once, at the sensor's
// column times; each beam's ray leaves from its beam origin along the direction of Ouster's
// published range-to-xyz formula, so the project's Ouster decoder puts each return where the
// surface is. Packets are encoded by lidartag/driver/ouster/encoder.hpp; the metadata the
// capture needs is ouster_sensor_info().
#pragma once

#include <cstdint>
#include <vector>

#include "lidartag/driver/ouster/metadata.hpp"
#include "lidartag/sim/geometry.hpp"
#include "lidartag/sim/packetizer.hpp"
#include "lidartag/sim/scene.hpp"
#include "lidartag/sim/tag_target.hpp"
#include "lidartag/sim/truth.hpp"

namespace lidartag::sim {

struct RunStats;

// The simulated sensor's serial number and initialization id (in its packets and metadata).
inline constexpr uint64_t kOusterSimSerial = 992000000001;
inline constexpr uint32_t kOusterSimInitId = 0x51a7;

// What the scene's Ouster sensor reports as its metadata (nominal_sensor_info() of its model,
// mode and profile, with the simulated serial number and init id). Requires sensor.ouster.
driver::ouster::SensorInfo ouster_sensor_info(const SensorOptions& sensor);

// The Simulator's run for an Ouster sensor: a lead-in of the last two packets of frame 0, then
// frames 1..rotations (truth rotation i is frame i + 1, stamped with its column 0's time), then
// the first two packets of the next frame, so a frame-id batcher delivers exactly `rotations`
// complete frames. Lidar packets on port 7502, captured when their last column ends.
Truth run_ouster(const Scene& scene, const World& world, const std::vector<TagTarget>& tags,
                 int rotations, uint64_t seed, const PacketCallback& emit, RunStats* stats);

}  // namespace lidartag::sim
