#include "lidartag/detector/fused_grid.hpp"

#include <algorithm>

namespace lidartag::detector {

double fused_grid_score(const RkhsDictionary& dict, int f, std::span<const float> votes,
                        std::span<const float> counts, double full_cell_votes) {
  const auto cells = static_cast<size_t>(dict.width() * dict.width());
  if (f < 0 || f >= dict.functions() || votes.size() < cells || counts.size() < cells ||
      !(full_cell_votes > 0.0))
    return -1.0;
  const float* signs = dict.signs(f);
  double agree = 0.0, most = 0.0;
  for (size_t i = 0; i < cells; ++i) {
    const double n = counts[i];
    if (!(n > 0.0)) continue;
    agree += signs[i] * votes[i] / std::max(n, full_cell_votes);
    most += std::min(n, full_cell_votes) / full_cell_votes;
  }
  return most > 0.0 ? 0.5 * (1.0 + agree / most) : -1.0;
}

bool fused_grid_confirms(const RkhsDictionary& dict, int f, std::span<const float> votes,
                         std::span<const float> counts, double full_cell_votes, double margin_cells,
                         double min_score, double fused_min_score, double fused_min_margin_cells) {
  return margin_cells >= fused_min_margin_cells &&
         fused_grid_score(dict, f, votes, counts, full_cell_votes) >=
             std::max(min_score, fused_min_score);
}

}  // namespace lidartag::detector
