// Helpers for the simulator tests: run a scene, keep its packets, decode them with the project's
// own Decoder and ScanBatcher.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "driver/keep_all.hpp"
#include "lidartag/driver/scan_batcher.hpp"
#include "lidartag/driver/velodyne/decoder.hpp"
#include "lidartag/sim/simulator.hpp"

namespace lidartag::sim::testing {

struct Packet {
  std::vector<uint8_t> payload;
  int64_t time_ns = 0;
  uint16_t port = 0;
};

struct Capture {
  std::vector<Packet> packets;
  Truth truth;
  RunStats stats;
};

inline Capture simulate(const Scene& scene, int rotations, uint64_t seed) {
  Capture c;
  Simulator sim(scene);
  c.truth = sim.run(
      rotations, seed,
      [&](std::span<const uint8_t> p, int64_t t, uint16_t port) {
        c.packets.push_back({{p.begin(), p.end()}, t, port});
      },
      &c.stats);
  return c;
}

// Keeps every finished rotation, each in a scan of its own (sized by the batcher).
using CollectSink = velodyne::testing::KeepAll;

struct Decoded {
  std::unique_ptr<CollectSink> sink;
  std::vector<Scan*> complete;  // complete rotations in order
  size_t bad_packets = 0;
  size_t data_packets = 0;
};

inline Decoded decode(const Capture& c, const Scene& scene) {
  using namespace velodyne;
  const ModelSpec& spec = model_spec(scene.sensor.model);
  Decoder decoder(Calibration::builtin(scene.sensor.model));
  SensorClock clock;
  Decoded d;
  d.sink = std::make_unique<CollectSink>();
  driver::BatcherOptions bo;
  bo.cut_azimuth_deg = scene.sensor.cut_azimuth_deg;
  driver::ScanBatcher batcher = velodyne::make_batcher(spec, scene.sensor.return_mode, bo);
  auto packet = std::make_unique<DecodedPacket>();
  for (const Packet& p : c.packets) {
    if (p.port != kDefaultDataPort) continue;
    ++d.data_packets;
    if (decoder.decode(p.payload, clock, p.time_ns, *packet) != DecodeStatus::kOk) {
      ++d.bad_packets;
      continue;
    }
    d.sink->keep(batcher.add(*packet, d.sink->current()));
  }
  while (batcher.flush(d.sink->current())) d.sink->keep(true);
  for (Scan* s : d.sink->scans)
    if (s->complete) d.complete.push_back(s);
  return d;
}

}  // namespace lidartag::sim::testing
