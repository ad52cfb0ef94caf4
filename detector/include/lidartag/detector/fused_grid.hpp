// The fused grid of a track (issue 33's far edge): per cell of the marker, the votes of every
// rotation's points summed in the track's frame. Its score for a function of the family says how
// well the whole grid, not the rotations one at a time, agrees with that code.
#pragma once

#include <span>

#include "lidartag/detector/rkhs_decoder.hpp"

namespace lidartag::detector {

// The normalised score of function f (code and quarter turns, RkhsDictionary numbering) on a
// fused grid: each cell's mean vote m = votes / max(counts, full_cell_votes) (+1 white, -1 black;
// a cell with fewer than full_cell_votes votes counts proportionally less) against the
// function's sign s on every cell of the marker (the white ring and the black border included:
// clutter and blank boards disagree there), (1 + sum s m / sum w) / 2 with w = min(counts,
// full_cell_votes) / full_cell_votes the most a cell can add. 1: every cell seen agrees fully;
// 0.5: no evidence either way; -1 when no cell was seen. `votes` and `counts` have width^2
// entries, row-major in the function's frame.
double fused_grid_score(const RkhsDictionary& dict, int f, std::span<const float> votes,
                        std::span<const float> counts, double full_cell_votes);

// The far edge's confirmation by the fused grid, for a track whose rotations' mean normalised
// score stays below the detector's min_score (a VLP-32C's 1.2 m tag at 32 m and 45 degrees: each
// rotation's 35-50 points fit and decode at 0.73-0.80 for the right code, while their votes,
// fused, agree with it at 0.87-0.94): the fused grid's score of the leading function f must reach
// max(min_score, fused_min_score) and the leader's margin over every other function, in cells,
// fused_min_margin_cells (the tracker's options TrackerOptions::fused_min_score and
// fused_min_margin_cells, where their defaults are argued).
bool fused_grid_confirms(const RkhsDictionary& dict, int f, std::span<const float> votes,
                         std::span<const float> counts, double full_cell_votes, double margin_cells,
                         double min_score, double fused_min_score, double fused_min_margin_cells);

}  // namespace lidartag::detector
