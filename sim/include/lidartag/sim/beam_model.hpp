// What one laser beam reports, from the surfaces its footprint touches: echo formation, mixed and
// missing returns at depth and black/white edges (the paper's Fig. 2), detection limits, the
// return-mode choice, and range/intensity noise.
#pragma once

#include <array>
#include <span>

#include "lidartag/driver/velodyne/sensor_model.hpp"
#include "lidartag/sim/random.hpp"
#include "lidartag/sim/scene.hpp"

namespace lidartag::sim {

// One ray of a beam's footprint.
struct SubReturn {
  bool hit = false;
  double range = 0.0;         // metres along the ray
  double reflectivity = 0.0;  // of the surface hit
  int tag = -1;               // tag marker hit, or -1
};

// A return the sensor can report.
struct Echo {
  double range = 0.0;         // metres
  double reflectivity = 0.0;  // apparent: surface reflectivity x the footprint fraction it fills
  int tag = -1;               // the tag marker under most of the echo's footprint, or -1
  double strength() const { return reflectivity / (range * range); }
};

inline constexpr int kMaxEchoes = 4;

struct BeamEchoes {
  int count = 0;
  std::array<Echo, kMaxEchoes> echo{};  // sorted by range
};

// Footprint sample offsets (horizontal, vertical) in radians for `samples` = 1, 5 or 9.
int footprint_offsets(const NoiseOptions& noise, std::array<std::array<double, 2>, 9>& out);

// Groups the footprint's sub-returns into echoes (sub-returns within echo_separation_m merge into
// one echo at their energy-weighted range: a mixed return), then applies the artefacts: dropout,
// missing or merged returns on depth edges, missing returns on reflectivity edges, and the
// inverse-square detection threshold. Exact (no noise) ranges and reflectivities.
BeamEchoes form_echoes(std::span<const SubReturn> subs, const NoiseOptions& noise, Rng& rng);

// What the sensor reports in `mode`: out[0] the strongest (kStrongest), the last (kLast), or in
// dual mode the last; out[1] in dual mode the strongest, or the second strongest when the
// strongest is also the last (identical to out[0] with a single echo). Returns how many distinct
// echoes out holds (0, 1 or 2).
int select_returns(const BeamEchoes& echoes, velodyne::ReturnMode mode, std::array<Echo, 2>& out);

// Adds Gaussian range and reflectivity noise.
Echo add_noise(const Echo& echo, const NoiseOptions& noise, Rng& rng);

}  // namespace lidartag::sim
