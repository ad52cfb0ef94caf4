// The fused grid's score and the far edge's confirmation by it (issue 33): a grid that is a code
// scores 1 for it and less for every other code; cells seen less count less; no evidence is no
// score; the confirmation needs both the score and the strict margin.
#include "lidartag/detector/fused_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/tracker.hpp"

namespace lidartag::detector {
namespace {

struct Grid {
  std::vector<float> votes, counts;
};

// Every cell voted `n` times with function f's sign.
Grid grid_of(const RkhsDictionary& dict, int f, float n) {
  const auto cells = static_cast<size_t>(dict.width() * dict.width());
  Grid g{std::vector<float>(cells), std::vector<float>(cells, n)};
  for (size_t i = 0; i < cells; ++i) g.votes[i] = n * dict.signs(f)[i];
  return g;
}

TEST(FusedGrid, AGridThatIsACodeScoresOneForItAndLessForEveryOtherFunction) {
  const RkhsDictionary dict(tags::builtin_family("tag16h5"));
  const int f = 4 * 7 + 1;  // code 7, one quarter turn
  const Grid g = grid_of(dict, f, 6.0f);
  EXPECT_DOUBLE_EQ(fused_grid_score(dict, f, g.votes, g.counts, 4.0), 1.0);
  for (int other = 0; other < dict.functions(); ++other) {
    if (other == f) continue;
    EXPECT_LT(fused_grid_score(dict, other, g.votes, g.counts, 4.0), 1.0) << other;
  }
}

TEST(FusedGrid, CellsSeenLessCountLessAndNoEvidenceIsNoScore) {
  const RkhsDictionary dict(tags::builtin_family("tag16h5"));
  const int f = 4 * 3;
  Grid g = grid_of(dict, f, 4.0f);
  // One cell with a single vote against f: it weighs a quarter of a fully seen cell.
  const auto cells = static_cast<double>(g.votes.size());
  g.votes[20] = -dict.signs(f)[20];
  g.counts[20] = 1.0f;
  const double most = cells - 1.0 + 0.25;
  EXPECT_NEAR(fused_grid_score(dict, f, g.votes, g.counts, 4.0),
              0.5 * (1.0 + (cells - 1.0 - 0.25) / most), 1e-6);
  const std::vector<float> zero(g.votes.size(), 0.0f);
  EXPECT_EQ(fused_grid_score(dict, f, zero, zero, 4.0), -1.0);
  // Votes that cancel: no evidence either way.
  const std::vector<float> twos(g.votes.size(), 2.0f);
  EXPECT_DOUBLE_EQ(fused_grid_score(dict, f, zero, twos, 4.0), 0.5);
  // Bad arguments: no score.
  EXPECT_EQ(fused_grid_score(dict, -1, g.votes, g.counts, 4.0), -1.0);
  EXPECT_EQ(fused_grid_score(dict, dict.functions(), g.votes, g.counts, 4.0), -1.0);
  EXPECT_EQ(fused_grid_score(dict, f, std::span<const float>(g.votes).first(3), g.counts, 4.0),
            -1.0);
  EXPECT_EQ(fused_grid_score(dict, f, g.votes, g.counts, 0.0), -1.0);
}

// The confirmation: the fused score at max(min_score, fused_min_score) and the strict margin
// (TrackerOptions' defaults, 0.9 and 1 cell, and other values). A grid of another code (a
// wrong-code tag) leading with a margin below fused_min_margin_cells, or a grid of blank board
// (every cell white), never confirms.
TEST(FusedGrid, ConfirmationNeedsTheScoreAndTheStrictMargin) {
  const RkhsDictionary dict(tags::builtin_family("tag16h5"));
  const int f = 4 * 11 + 2;
  const Grid g = grid_of(dict, f, 8.0f);
  const TrackerOptions o;
  const double score = o.fused_min_score, margin = o.fused_min_margin_cells;
  EXPECT_TRUE(fused_grid_confirms(dict, f, g.votes, g.counts, 4.0, margin, 0.8, score, margin));
  EXPECT_FALSE(fused_grid_confirms(dict, f, g.votes, g.counts, 4.0, 0.99, 0.8, score, margin));
  EXPECT_FALSE(fused_grid_confirms(dict, f, g.votes, g.counts, 4.0, 5.0, 1.01, score, margin));
  // The thresholds are the caller's: a margin of 0.99 cells passes a gate of 0.9 cells, and a
  // fused score gate above the grid's own score refuses it.
  EXPECT_TRUE(fused_grid_confirms(dict, f, g.votes, g.counts, 4.0, 0.99, 0.8, score, 0.9));
  const double own = fused_grid_score(dict, f, g.votes, g.counts, 4.0);
  EXPECT_FALSE(fused_grid_confirms(dict, f, g.votes, g.counts, 4.0, 5.0, 0.8,
                                   std::nextafter(own, 2.0), margin));
  // Another code's grid: the score of f falls below fused_min_score wherever the codes differ in
  // enough cells; with a small margin it never confirms.
  int below = 0;
  for (int code = 0; code < 30; ++code) {
    if (code == 11) continue;
    const Grid other = grid_of(dict, 4 * code + 2, 8.0f);
    below += fused_grid_score(dict, f, other.votes, other.counts, 4.0) < score ? 1 : 0;
    EXPECT_FALSE(
        fused_grid_confirms(dict, f, other.votes, other.counts, 4.0, 0.74, 0.8, score, margin));
  }
  EXPECT_GT(below, 0);
  // A blank board: every cell white, so that the black border disagrees with every code.
  const auto cells = g.votes.size();
  const std::vector<float> white(cells, 8.0f);
  for (int h = 0; h < dict.functions(); ++h)
    EXPECT_FALSE(fused_grid_confirms(dict, h, white, white, 4.0, 5.0, 0.8, score, margin)) << h;
}

}  // namespace
}  // namespace lidartag::detector
