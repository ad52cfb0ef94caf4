#include "lidartag/sim/beam_model.hpp"

#include <algorithm>
#include <cmath>

namespace lidartag::sim {

int footprint_offsets(const NoiseOptions& noise, std::array<std::array<double, 2>, 9>& out) {
  // Half the full divergence: the footprint's edge.
  const double h = noise.divergence_h_mrad * 1e-3 / 2.0;
  const double v = noise.divergence_v_mrad * 1e-3 / 2.0;
  out[0] = {0.0, 0.0};
  if (noise.footprint_samples <= 1) return 1;
  if (noise.footprint_samples < 9) {
    out[1] = {-h, 0.0};
    out[2] = {h, 0.0};
    out[3] = {0.0, -v};
    out[4] = {0.0, v};
    return 5;
  }
  int n = 1;
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      if (i != 0 || j != 0) out[static_cast<size_t>(n++)] = {i * h, j * v};
  return 9;
}

namespace {

// Energy-weighted merge of sub-returns [begin, end) of `hits` (sorted by range); each sub-return
// carries 1/total of the beam's energy.
Echo merge(std::span<const SubReturn> hits, size_t total) {
  double energy = 0.0, weighted_range = 0.0, plain_range = 0.0;
  std::array<int, 8> tag_votes{};
  std::array<int, 8> tag_ids{};
  size_t tags = 0;
  for (const SubReturn& s : hits) {
    energy += s.reflectivity;
    weighted_range += s.reflectivity * s.range;
    plain_range += s.range;
    size_t k = 0;
    while (k < tags && tag_ids[k] != s.tag) ++k;
    if (k == tags && tags < tag_ids.size()) tag_ids[tags++] = s.tag;
    if (k < tags) ++tag_votes[k];
  }
  Echo e;
  e.range = energy > 0.0 ? weighted_range / energy : plain_range / static_cast<double>(hits.size());
  e.reflectivity = energy / static_cast<double>(total);
  // The tag under more than half of this echo's sub-returns.
  for (size_t k = 0; k < tags; ++k)
    if (2 * static_cast<size_t>(tag_votes[k]) > hits.size()) e.tag = tag_ids[k];
  return e;
}

}  // namespace

BeamEchoes form_echoes(std::span<const SubReturn> subs, const NoiseOptions& noise, Rng& rng) {
  BeamEchoes out;
  if (rng.bernoulli(noise.dropout)) return out;
  std::array<SubReturn, 9> hits{};
  size_t n = 0;
  for (const SubReturn& s : subs)
    if (s.hit && n < hits.size()) hits[n++] = s;
  if (n == 0) return out;
  // Insertion by range (at most 9 entries). std::sort here gives GCC 12 at -O3 a false
  // -Warray-bounds inside its heap fallback.
  const auto closer = [](const SubReturn& a, const SubReturn& b) { return a.range < b.range; };
  for (auto it = hits.begin() + 1; it < hits.begin() + static_cast<std::ptrdiff_t>(n); ++it)
    std::rotate(std::upper_bound(hits.begin(), it, *it, closer), it, it + 1);
  const std::span<const SubReturn> sorted(hits.data(), n);

  double rmin = sorted.front().range, rmax = sorted.back().range;
  double imin = sorted.front().reflectivity, imax = imin;
  for (const SubReturn& s : sorted) {
    imin = std::min(imin, s.reflectivity);
    imax = std::max(imax, s.reflectivity);
  }
  // A depth edge: the footprint spans surfaces at different depths, or partly misses.
  const bool depth_edge = rmax - rmin > noise.depth_edge_m || n < subs.size();
  const bool intensity_edge = !depth_edge && imax - imin > noise.intensity_edge;
  bool merge_all = false;
  if (depth_edge) {
    if (rng.bernoulli(noise.depth_edge_missing)) return out;
    merge_all = rng.bernoulli(noise.depth_edge_mixed);
  } else if (intensity_edge && rng.bernoulli(noise.intensity_edge_missing)) {
    return out;
  }

  size_t begin = 0;
  for (size_t i = 1; i <= n; ++i) {
    const bool split =
        i == n || (!merge_all && sorted[i].range - sorted[i - 1].range > noise.echo_separation_m);
    if (!split) continue;
    Echo e = merge(sorted.subspan(begin, i - begin), subs.size());
    begin = i;
    // Inverse-square detection limit on the apparent (0..100 diffuse) reflectivity.
    const double need = noise.detect_reflectivity_10m * (e.range / 10.0) * (e.range / 10.0);
    if (e.reflectivity < need || out.count == kMaxEchoes) continue;
    out.echo[static_cast<size_t>(out.count++)] = e;
  }
  return out;
}

int select_returns(const BeamEchoes& echoes, velodyne::ReturnMode mode, std::array<Echo, 2>& out) {
  if (echoes.count == 0) return 0;
  const auto count = static_cast<size_t>(echoes.count);
  size_t strongest = 0;
  for (size_t i = 1; i < count; ++i)
    if (echoes.echo[i].strength() > echoes.echo[strongest].strength()) strongest = i;
  const size_t last = count - 1;
  switch (mode) {
    case velodyne::ReturnMode::kStrongest:
      out[0] = echoes.echo[strongest];
      return 1;
    case velodyne::ReturnMode::kLast:
      out[0] = echoes.echo[last];
      return 1;
    case velodyne::ReturnMode::kDual:
      break;
  }
  out[0] = echoes.echo[last];
  if (count == 1) {
    out[1] = out[0];
    return 1;
  }
  size_t other = strongest;
  if (strongest == last) {  // second strongest
    other = last == 0 ? 1 : 0;
    for (size_t i = 0; i < last; ++i)
      if (echoes.echo[i].strength() > echoes.echo[other].strength()) other = i;
  }
  out[1] = echoes.echo[other];
  return 2;
}

Echo add_noise(const Echo& echo, const NoiseOptions& noise, Rng& rng) {
  Echo e = echo;
  e.range = rng.normal(e.range, noise.range_sigma_m);
  e.reflectivity = std::clamp(rng.normal(e.reflectivity, noise.intensity_sigma), 0.0, 255.0);
  return e;
}

}  // namespace lidartag::sim
