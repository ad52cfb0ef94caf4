// Stage 6 (paper Sec. VI): decoding by inner products of RKHS functions, eq. (18) [InnerProduct]
// with the kernels eqs. (19) [kernel] and (21) [kernel_intensity] and the 3-D lifting, eq. (22),
// against a function dictionary of every code x 4 rotations built from the family's code words.
// (Equations are numbered as in the paper's PDF; docs/detector.md lists them.)
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "lidartag/detector/tag_family.hpp"
#include "lidartag/detector/types.hpp"

namespace lidartag::detector {

struct DecodeOptions {
  // Template points per cell along each axis (the dictionary functions' representers).
  // Default 2.
  int samples_per_cell = 2;
  // Length scale of the spatial kernel eq. (19), in cells. Default 0.25: the paper's half a
  // bit lets the eight neighbours of an isolated cell outweigh it (flipped-cell tests mis-decode).
  double length_scale_cells = 0.25;
  // l_I of eq. (21) on intensities normalised to black 0, white 1. Default 0.35 (the
  // paper's 10 of 255 assumes one fixed contrast).
  double intensity_length_scale = 0.35;
  // 3-D lifting, eq. (22): a white point moves this many cells along the normal. Default 0.5 (the
  // paper's t / (2 (d+4)) for the brightest point).
  double lift_cells = 0.5;
  // Fewest intensity units between the black and the white level. Default 8.
  double min_contrast = 8.0;
  // Decision: the best normalised score (1 = every cell agrees) must reach min_score and beat the
  // best other function of the family (another code or rotation) by min_margin_bits payload
  // cells' worth of evidence. min_score default 0.8: tags decode at 0.93-1.0 in bench_accuracy up
  // to 20 m, while an under-sampled tag read as another family scored 0.57-0.65 in
  // pcaps/outdoor.pcap. min_margin_bits default 1.25: the only wrong ID of bench_accuracy (a VLP-16
  // at 6 m whose beams miss payload cells) had a margin of 1.04; correct reads below 1.25 occur
  // only at the sampling limit (VLP-32C at 18-20 m and 45 degrees, VLP-16 at 6-8 m). With tag16h5's
  // 5-bit distance one wrong cell still decodes.
  double min_score = 0.8;
  double min_margin_bits = 1.25;
  // The margin a decode needs when the tag's place along one axis was searched (a square mount:
  // no ring crosses its top or bottom edge, decode_cluster tries it at shifts a half cell apart),
  // cells. Default 3.0: every shift adds hypotheses; over 31 runs of 20 rotations of a
  // square-mounted VLP-16 1.2 m tag16h5 at 5-7 m, wrong codes at a shifted place led with margins
  // of 1.6-2.5 (15 rotations at 1.25, 1 at 2.5), none at 3.0 (61 runs). Only for a square mount
  // (square_mount_axis in decode_cluster.hpp), not a sparse diamond's short search.
  double min_margin_bits_searched = 3.0;
  // Score the dictionary with TBB when it holds at least this many functions. Default 4096.
  int parallel_min_functions = 4096;
  // Most points decoded (evenly spaced over the cluster): about 8 per cell of a 16-bit family.
  // Default 512.
  int max_points = 512;
  // Also decode against every built-in family that is not configured, and reject a cluster that
  // one of them fits better (Rejection::kOtherFamily). Default true: a tag of another family
  // otherwise reads as some code of the configured one (a tag16h5 as tag25h9 in 29 of 36 rotations
  // at 2-12 m, scores up to 0.94), since the margin compares codes of one family only.
  bool reject_other_families = true;
  // A cluster below min_score is decoded against those families too (at its best shift only), for
  // a tracker's evidence over rotations, but only from this score on: below it the cluster is no
  // tag of any family (a checkerboard or a sign scores 0.01-0.6) and the check, most of its decode
  // cost (tag36h10's 9,280 functions), is skipped (Candidate::other_family_score stays -1).
  // Default 0.5.
  double other_family_min_score = 0.5;
  // A decoded point counts as seeing its cell only when it lies at least this many cells inside
  // the cell's borders (a beam's footprint near a border sees both colours): for the cell votes
  // (Candidate, ScanResult::cell_votes, evidence over rotations) and for seen_cells_lead. Default
  // 0.05 (7.5 mm on a 1.2 m tag16h5; a 3 mrad footprint is 18-24 mm wide at 6-8 m): a return that
  // near a border is mostly inside its cell, and its vote, scaled by its intensity, is weakened
  // rather than turned by the neighbour. bench_tracker with the tag's height spread: 0.1 -> 0.05
  // raised a VLP-16 at 8 m from 88 to 96 % of rotations, at 10 m face-on from 55 to 66 %, with no
  // wrong ID; at the sensor's height 0 gave a wrong ID (VLP-16, 6 m, 45 degrees).
  double vote_inset_cells = 0.05;
  // The margin counts every cell's evidence, also what the kernel spreads into cells no ring
  // crosses; on the returns that lie in the cells (vote_inset_cells), each cell its mean vote, the
  // decision must lead every other function by at least this many cells (seen_cells_lead), else
  // decode/ambiguous (a candidate for a tracker). Default 0.5: with the tag's height spread over a
  // beam spacing (bench_tracker), a VLP-16 at 7 m read code 25 as 2 twice with margins of 1.26 and
  // 1.46 cells that the seen cells barely supported; a VLP-16 at 10 m read code 4 as 0 with a
  // margin of 1.32 that no seen cell supported; a VLP-32C at 20 m turned 45 degrees read code 8
  // as 15 with 1.90, where one grey return (0.3 cell) was all the deciding cells held. About 5 %
  // of the right single-rotation reads there lead by less; the tracker carries them.
  double min_seen_margin_cells = 0.5;
  // A detection of one rotation needs at least this many returns per cell of its marker (the
  // points of the pose fit over total_width^2); a cluster with fewer that decodes is rejected as
  // decode/sparse and stays a candidate, evidence for a tracker. Default 1.4: a 1.2 m tag16h5
  // turned 45 degrees at 24 m of a VLP-32C returns 0.97-1.39 per cell, and bench_tracker (every
  // code, 510 rotations) saw 5 wrong IDs in the 371 rotations decoded alone, at 1.16-1.31 per
  // cell, with scores (0.86-0.98), margins (1.5-2.6 cells) and fit costs like the right reads';
  // none in 524 at 22 m (1.11-1.61, 40 % of them kept), 583 at 20 m (1.25-1.98, 99 % kept) or
  // 397 of a VLP-16 at 10 m turned 45 degrees (1.36-1.53, 97 % kept). Returns per cell along the
  // rings alone do not tell the wrong reads apart (0.8-1.1 at 24 m and at 22 m): both the ring
  // spacing and the returns along a ring count. validation.min_returns_per_cell (default 1) is
  // where a cluster stops being looked at at all.
  double min_returns_per_cell = 1.4;
};

// The function dictionary of one family: for code k and quarter turn q (clockwise, seen from the
// front), the sign (+1 white, -1 black) of each of the W x W cells of the rotated marker image.
// Scores are computed on the cells where functions differ (the payload of the built-in families):
// the other cells (white ring, black border) add the same to every function's inner product.
class RkhsDictionary {
 public:
  explicit RkhsDictionary(const tags::TagFamily& family);
  const tags::TagFamily& family() const { return family_; }
  int width() const { return width_; }
  int functions() const { return static_cast<int>(signs_.size()) / (width_ * width_); }
  // Cell signs of function f = 4 * code_index + quarter_turns, row-major, row 0 at the top.
  const float* signs(int f) const {
    return signs_.data() + static_cast<size_t>(f) * static_cast<size_t>(width_ * width_);
  }
  // Cells (row-major indices) whose sign is not the same in every function, ascending.
  const std::vector<int>& varying_cells() const { return varying_; }
  // The sign of function f on varying cell k (+1 white, -1 black).
  float varying_sign(int f, size_t k) const {
    const uint8_t byte = chunks_[static_cast<size_t>(f) * chunk_count() + k / 8];
    return (byte >> (k % 8)) & 1U ? 1.0f : -1.0f;
  }
  // The varying cells in groups of 8, a byte per group and function (bit i: cell 8 g + i is
  // white): a function's score is a sum of one table entry per group (decode_prepared).
  size_t chunk_count() const { return (varying_.size() + 7) / 8; }
  const uint8_t* chunks(int f) const {
    return chunks_.data() + static_cast<size_t>(f) * chunk_count();
  }

 private:
  tags::TagFamily family_;
  int width_ = 0;
  std::vector<float> signs_;
  std::vector<int> varying_;
  std::vector<uint8_t> chunks_;  // functions x chunk_count()
};

// The dictionaries of the built-in families whose names are not among `configured` (the families
// a detector or tracker looks for): what decode.reject_other_families decodes against, in the
// detector one rotation at a time and in the tracker over a track's votes.
std::vector<RkhsDictionary> other_builtin_dictionaries(std::span<const std::string> configured);

// The black and the white intensity level of a cluster: the points split around their mean
// intensity, the median of each side. Invalid for no points.
struct IntensityLevels {
  float black = 0.0f;
  float white = 0.0f;
  bool valid = false;
};

// A point as every family decodes it: coordinates in units of the tag size, intensity label (0
// black, 1 white).
struct DecodePoint {
  double xn = 0, yn = 0, zn = 0;
  double label = 0;
};

// Scratch memory of decode_tag, reused between calls (no allocation once grown).
struct DecodeWorkspace {
  std::vector<DecodePoint> prepared;  // the points of prepare_decode
  IntensityLevels levels;             // their levels
  bool prepared_ok = false;           // enough points, a valid size and levels
  std::vector<double> acc;            // per cell: white minus black kernel sums
  std::vector<float> evidence;  // per cell: the same in float, what the functions are scored on
  std::vector<double> ex, ez;   // per point: kernel factors of the sample columns and rows
  std::vector<float> exps;      // per point: its four kernel exponentials (their arguments first)
  // per point: the sample columns c0-c1 and rows r0-r1 its kernel reaches (-1: none)
  std::vector<std::array<int, 4>> reach;
  std::vector<float> sorted;   // intensity medians
  std::vector<float> varying;  // the evidence on the dictionary's varying cells
  std::vector<float> tables;   // per group of 8 varying cells: the sum for each sign pattern
  std::vector<float> scores;   // per function, without the cells common to all functions
  // Of the last decode_prepared that scored: what the cells common to every function add, and
  // the sum of the evidence's magnitudes (a function's normalised score is (scores + common) /
  // total).
  double common = 0.0;
  double total = 0.0;
  double payload = 0.0;  // mean |evidence| of a payload cell: the unit of margins in cells
  // The cell evidence depends on the points and the family's width only: kept per width until
  // the next prepare_decode, so families of the same width share it.
  struct Evidence {
    int width = 0;
    std::vector<float> cells;
    double total = 0.0;  // sum of |evidence|
  };
  std::array<Evidence, 4> by_width;
  size_t widths = 0;  // entries of by_width in use
};

struct DecodeResult {
  Rejection rejection = Rejection::kLowContrast;
  int code_index = -1;        // index into the family's codes
  int quarter_turns = 0;      // the marker image, turned this many times clockwise, fits the points
  double score = 0.0;         // normalised inner product of the best function, <= 1
  double margin_bits = 0.0;   // best minus second best, in mean payload cells' worth of evidence
  int function = -1;          // the best dictionary function (4 * code_index + quarter_turns)
  int second_function = -1;   // the runner-up
  double second_score = 0.0;  // its normalised score
  // Payload cells' worth of evidence per unit of normalised score: margin_bits = (score -
  // second_score) * cells_per_score. Lets a caller compare hypotheses decoded separately.
  double cells_per_score = 0.0;
};

// The levels of `points` (uses ws.sorted).
IntensityLevels intensity_levels(std::span<const ClusterPoint> points, DecodeWorkspace& ws);

// decode_tag in two steps, for several families decoding the same points: prepare_decode keeps
// what does not depend on the family in `ws`, decode_prepared decodes it against one dictionary.
void prepare_decode(std::span<const ClusterPoint> points, const IntensityLevels& levels, double t,
                    DecodeWorkspace& ws);
DecodeResult decode_prepared(const RkhsDictionary& dict, const DecodeOptions& opt,
                             DecodeWorkspace& ws);

// After a decode_prepared that scored (DecodeResult::function >= 0): the normalised score of every
// function of its dictionary into `out` (one per function, <= 1), from ws.scores.
void normalised_scores(const DecodeWorkspace& ws, std::vector<float>& out);

// The cell of a w x w grid (row-major; column from -y, row from +z) that a point at (yn, zn) of
// the tag frame (units of the tag size) lies at least `inset` cells inside, or -1 (outside the
// grid, or nearer a border: it may have its neighbour's colour). The cells whose points vote: the
// cell votes, seen_cells_lead and the tracker use this one layout.
int vote_cell(double yn, double zn, int w, double inset);

// A point's vote from its intensity label (0 black, 1 white): 2 label - 1, clamped to [-1, 1].
inline float point_vote(double label) {
  return static_cast<float>(std::clamp(2.0 * label - 1.0, -1.0, 1.0));
}

// Per cell of a w x w grid: the summed votes of the prepared points that lie at least `inset`
// cells inside it (vote_cell, point_vote), and their number.
void cell_votes(std::span<const DecodePoint> prepared, int w, double inset,
                std::vector<float>& votes, std::vector<float>& counts);

// How far `function` leads every other function of `dict` on the cells' own returns: each cell's
// mean vote (cell_votes; 0 for a cell without one), summed over the cells where the two differ, in
// cells (1 = one cell seen clearly in the function's colour). A cell no ring crosses, or crosses
// only near its border, carries only its neighbours' kernel tails in the decoder's evidence; a
// lead near 0 means that the cells actually seen do not tell the function from another.
// Overwrites ws.varying, ws.tables and ws.scores.
double seen_cells_lead(const RkhsDictionary& dict, int function, std::span<const float> votes,
                       std::span<const float> counts, const DecodeOptions& opt,
                       DecodeWorkspace& ws);

// `points` are pulled back into the estimated tag frame (x normal, y right, z up, metres) with
// their intensities; t is the tag size.
DecodeResult decode_tag(std::span<const ClusterPoint> points, double t, const RkhsDictionary& dict,
                        const DecodeOptions& opt, DecodeWorkspace& ws);
// The same with the levels of intensity_levels(points) computed once: they do not change when the
// points move (shifts) or another family is tried.
DecodeResult decode_tag(std::span<const ClusterPoint> points, const IntensityLevels& levels,
                        double t, const RkhsDictionary& dict, const DecodeOptions& opt,
                        DecodeWorkspace& ws);

}  // namespace lidartag::detector
