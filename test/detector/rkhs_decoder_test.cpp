// Stage 6: RKHS decoding against every code x 4 rotations of every built-in family.
#include "lidartag/detector/rkhs_decoder.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "count_allocations.hpp"

namespace lidartag::detector {
namespace {

// Noise-free points pulled back into the tag frame: `per_cell` x `per_cell` per cell of the
// marker image turned `q` times clockwise, size t = 1.
void synth(const tags::TagFamily& fam, int id, int q, const std::vector<int>& flips, int per_cell,
           std::vector<ClusterPoint>& out) {
  const int w = fam.total_width;
  auto img = fam.render(fam.codes[static_cast<size_t>(id)]);
  for (int k = 0; k < q; ++k) {
    std::vector<uint8_t> rot(img.size());
    for (int r = 0; r < w; ++r)
      for (int c = 0; c < w; ++c)
        rot[static_cast<size_t>(c * w + (w - 1 - r))] = img[static_cast<size_t>(r * w + c)];
    img.swap(rot);
  }
  for (int f : flips) img[static_cast<size_t>(f)] ^= 1;
  out.clear();
  const int n = w * per_cell;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      ClusterPoint p;
      p.y = static_cast<float>((c + 0.5) / n - 0.5);
      p.z = static_cast<float>(0.5 - (r + 0.5) / n);
      p.intensity = img[static_cast<size_t>((r / per_cell) * w + c / per_cell)] ? 200.0f : 30.0f;
      out.push_back(p);
    }
}

TEST(RkhsDecoder, DictionaryHoldsEveryCodeInFourRotations) {
  const auto& fam = tags::builtin_family("tag16h5");
  const RkhsDictionary d(fam);
  EXPECT_EQ(d.functions(), 4 * fam.ncodes());
  EXPECT_EQ(d.width(), 8);
  // Function 4k + 1 is function 4k turned clockwise: cell (r, c) moves to (c, W-1-r).
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) EXPECT_EQ(d.signs(1)[c * 8 + (7 - r)], d.signs(0)[r * 8 + c]);
}

// Every code of every built-in family decodes to itself under all 4 rotations. tag36h10 and
// tag36h11 check each code in one rotation (cycling through the four) to keep the suite fast.
TEST(RkhsDecoder, EveryCodeOfEveryFamilyDecodesToItself) {
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  for (const auto& name : tags::builtin_family_names()) {
    const auto& fam = tags::builtin_family(name);
    const RkhsDictionary dict(fam);
    const bool big = fam.ncodes() > 100;
    int failures = 0;
    for (int id = 0; id < fam.ncodes(); ++id)
      for (int q = 0; q < 4; ++q) {
        if (big && q != id % 4) continue;
        synth(fam, id, q, {}, 3, pts);
        const DecodeResult r = decode_tag(pts, 1.0, dict, DecodeOptions{}, ws);
        // tag16h6 (the paper's set) has codes only 3 bits apart: a correct decode may be flagged
        // ambiguous there, never decoded as another code.
        const bool ok = r.code_index == id && r.quarter_turns == q &&
                        (r.rejection == Rejection::kNone ||
                         (name == "tag16h6" && r.rejection == Rejection::kAmbiguous));
        if (!ok && ++failures < 5)
          ADD_FAILURE() << name << " id " << id << " q " << q << " -> " << r.code_index << " q "
                        << r.quarter_turns << " score " << r.score << " margin " << r.margin_bits;
        if (r.rejection == Rejection::kNone) {
          EXPECT_GT(r.score, 0.9);
        }
      }
    EXPECT_EQ(failures, 0) << name;
  }
}

// With up to (h - 1) / 2 flipped payload cells (h the family's Hamming distance: 2 for tag16h5,
// 4 for tag25h9) a tag decodes to itself or is rejected, never to another code.
TEST(RkhsDecoder, FlippedCellsNeverMisdecode) {
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  std::mt19937 rng(11);
  for (const char* name : {"tag16h5", "tag25h9"}) {
    const auto& fam = tags::builtin_family(name);
    const RkhsDictionary dict(fam);
    const int w = fam.total_width, b = fam.border_start() + 1, pw = fam.payload_width();
    std::uniform_int_distribution<int> cell(0, pw * pw - 1);
    std::array<int, 5> decoded{}, trials{};
    const int max_flips = (fam.min_hamming - 1) / 2;
    for (int flips = 1; flips <= max_flips; ++flips)
      for (int id = 0; id < fam.ncodes(); ++id) {
        std::vector<int> cells;
        while (static_cast<int>(cells.size()) < flips) {
          const int k = cell(rng);
          const int idx = (b + k / pw) * w + b + k % pw;
          if (std::find(cells.begin(), cells.end(), idx) == cells.end()) cells.push_back(idx);
        }
        synth(fam, id, id % 4, cells, 3, pts);
        const DecodeResult r = decode_tag(pts, 1.0, dict, DecodeOptions{}, ws);
        if (r.rejection == Rejection::kNone) {
          EXPECT_EQ(r.code_index, id) << name << " flips " << flips;
          EXPECT_EQ(r.quarter_turns, id % 4);
        }
        ++trials[static_cast<size_t>(flips)];
        decoded[static_cast<size_t>(flips)] += r.rejection == Rejection::kNone ? 1 : 0;
      }
    for (int k = 1; k <= max_flips; ++k)
      std::printf("%s: %d flipped cells: %d of %d decoded, the rest rejected\n", name, k,
                  decoded[static_cast<size_t>(k)], trials[static_cast<size_t>(k)]);
    EXPECT_GT(decoded[1], trials[1] * 3 / 4) << name;  // one wrong cell mostly still decodes
  }
}

TEST(RkhsDecoder, NoContrastIsRejected) {
  const RkhsDictionary dict(tags::builtin_family("tag16h5"));
  std::vector<ClusterPoint> pts;
  synth(dict.family(), 0, 0, {}, 3, pts);
  for (auto& p : pts) p.intensity = 100.0f + static_cast<float>(p.intensity > 100 ? 2 : 0);
  DecodeWorkspace ws;
  EXPECT_EQ(decode_tag(pts, 1.0, dict, DecodeOptions{}, ws).rejection, Rejection::kLowContrast);
}

TEST(RkhsDecoder, IntensityLevelsAreTheMediansOfEachSideOfTheMean) {
  std::vector<ClusterPoint> pts(7);
  // Mean 100: below it 10, 20, 90 (median 20); at or above it 100, 110, 120, 250 (median 120).
  const std::array<float, 7> in = {90.0f, 250.0f, 10.0f, 110.0f, 100.0f, 20.0f, 120.0f};
  for (size_t i = 0; i < pts.size(); ++i) pts[i].intensity = in[i];
  DecodeWorkspace ws;
  const IntensityLevels lv = intensity_levels(pts, ws);
  ASSERT_TRUE(lv.valid);
  EXPECT_EQ(lv.black, 20.0f);
  EXPECT_EQ(lv.white, 120.0f);
  for (auto& p : pts) p.intensity = 50.0f;  // one level only: nothing below the mean
  EXPECT_FALSE(intensity_levels(pts, ws).valid);
  EXPECT_FALSE(intensity_levels({}, ws).valid);
}

// Whole-number intensities in [0, 255] (a Velodyne's) are counted in a histogram, any other by
// sorting: shifted by half a unit, the same points must give the same levels shifted.
TEST(RkhsDecoder, WholeNumberIntensitiesGiveTheLevelsThatSortingGives) {
  std::mt19937 rng(7);
  DecodeWorkspace ws;
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<ClusterPoint> pts(1 + rng() % 300);
    const int spread = 1 + static_cast<int>(rng() % 255);
    for (auto& p : pts) p.intensity = static_cast<float>(rng() % static_cast<unsigned>(spread));
    const IntensityLevels whole = intensity_levels(pts, ws);
    for (auto& p : pts) p.intensity += 0.5f;
    const IntensityLevels sorted = intensity_levels(pts, ws);
    ASSERT_EQ(whole.valid, sorted.valid) << "trial " << trial;
    if (!whole.valid) continue;
    EXPECT_EQ(whole.black + 0.5f, sorted.black) << "trial " << trial;
    EXPECT_EQ(whole.white + 0.5f, sorted.white) << "trial " << trial;
  }
}

// The detector computes the levels once per cluster and decodes every shift and family with them:
// the same result as computing them in each call.
TEST(RkhsDecoder, DecodingWithPrecomputedLevelsGivesTheSameResult) {
  for (const char* name : {"tag16h5", "tag25h9", "tag36h11"}) {
    const RkhsDictionary dict(tags::builtin_family(name));
    std::vector<ClusterPoint> pts;
    synth(dict.family(), 2, 1, {dict.width() * 3 + 3}, 2, pts);
    DecodeWorkspace ws;
    const DecodeResult a = decode_tag(pts, 1.0, dict, DecodeOptions{}, ws);
    const DecodeResult b =
        decode_tag(pts, intensity_levels(pts, ws), 1.0, dict, DecodeOptions{}, ws);
    EXPECT_EQ(a.rejection, b.rejection) << name;
    EXPECT_EQ(a.function, b.function) << name;
    EXPECT_EQ(a.second_function, b.second_function) << name;
    EXPECT_EQ(a.score, b.score) << name;
    EXPECT_EQ(a.second_score, b.second_score) << name;
    EXPECT_EQ(a.margin_bits, b.margin_bits) << name;
    EXPECT_EQ(a.function, 9) << name;  // code 2, one quarter turn
    EXPECT_EQ(decode_tag(pts, IntensityLevels{}, 1.0, dict, DecodeOptions{}, ws).rejection,
              Rejection::kLowContrast)
        << name;
  }
}

// One preparation serves every family: decoding it against another dictionary in between leaves
// it as it was, and each family decodes it as decode_tag does.
TEST(RkhsDecoder, PreparedPointsDecodeAgainstSeveralFamilies) {
  const RkhsDictionary d16(tags::builtin_family("tag16h5")), d25(tags::builtin_family("tag25h9"));
  std::vector<ClusterPoint> pts;
  synth(d16.family(), 4, 2, {}, 2, pts);
  DecodeWorkspace ws, ref;
  prepare_decode(pts, intensity_levels(pts, ws), 1.0, ws);
  const DecodeResult first = decode_prepared(d16, DecodeOptions{}, ws);
  const DecodeResult other = decode_prepared(d25, DecodeOptions{}, ws);
  const DecodeResult again = decode_prepared(d16, DecodeOptions{}, ws);
  EXPECT_EQ(first.function, 18);  // code 4, two quarter turns
  EXPECT_EQ(first.rejection, Rejection::kNone);
  EXPECT_EQ(again.function, first.function);
  EXPECT_EQ(again.score, first.score);
  EXPECT_EQ(again.margin_bits, first.margin_bits);
  const DecodeResult other_ref = decode_tag(pts, 1.0, d25, DecodeOptions{}, ref);
  EXPECT_EQ(other.function, other_ref.function);
  EXPECT_EQ(other.score, other_ref.score);
  EXPECT_EQ(other.rejection, other_ref.rejection);
  // Too few points: nothing to decode.
  prepare_decode(std::span<const ClusterPoint>(pts.data(), 3), intensity_levels(pts, ws), 1.0, ws);
  EXPECT_EQ(decode_prepared(d16, DecodeOptions{}, ws).function, -1);
}

TEST(RkhsDecoder, ARandomPatternIsNotDecoded) {
  // Cells of random colour: the white ring and black border do not match any function.
  const RkhsDictionary dict(tags::builtin_family("tag16h5"));
  std::mt19937 rng(3);
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  int accepted = 0;
  for (int trial = 0; trial < 200; ++trial) {
    synth(dict.family(), 0, 0, {}, 3, pts);
    std::vector<float> cell(64);
    for (auto& c : cell) c = (rng() & 1) ? 200.0f : 30.0f;
    for (auto& p : pts) {
      const int c = std::clamp(static_cast<int>((p.y + 0.5f) * 8), 0, 7);
      const int r = std::clamp(static_cast<int>((0.5f - p.z) * 8), 0, 7);
      p.intensity = cell[static_cast<size_t>(r * 8 + c)];
    }
    accepted += decode_tag(pts, 1.0, dict, DecodeOptions{}, ws).rejection == Rejection::kNone;
  }
  EXPECT_EQ(accepted, 0);
}

TEST(RkhsDecoder, ReportsTheRunnerUpForComparisonsAcrossHypotheses) {
  const auto& fam = tags::builtin_family("tag16h5");
  const RkhsDictionary dict(fam);
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  synth(fam, 7, 1, {}, 3, pts);
  const DecodeResult r = decode_tag(pts, 1.0, dict, DecodeOptions{}, ws);
  ASSERT_EQ(r.rejection, Rejection::kNone);
  EXPECT_EQ(r.function, 4 * 7 + 1);
  EXPECT_NE(r.second_function, r.function);
  EXPECT_GE(r.second_function, 0);
  EXPECT_LT(r.second_score, r.score);
  EXPECT_NEAR(r.margin_bits, (r.score - r.second_score) * r.cells_per_score, 1e-4 * r.margin_bits);
}

// Scores are computed on the cells that differ between functions, plus the common cells once: the
// best and runner-up must be those of the full inner product with every function (first of equal
// scores), on clean, misaligned and noisy points of every family.
TEST(RkhsDecoder, BestAndRunnerUpAreThoseOfTheInnerProductWithEveryFunction) {
  std::mt19937 rng(17);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  for (const auto& name : tags::builtin_family_names()) {
    const auto& fam = tags::builtin_family(name);
    const RkhsDictionary dict(fam);
    const auto cells = static_cast<size_t>(dict.width() * dict.width());
    for (int trial = 0; trial < 12; ++trial) {
      synth(fam, static_cast<int>(rng() % fam.codes.size()), trial % 4, {}, 2, pts);
      // Misaligned by up to half a cell, noisy intensities, a third of the points dropped.
      const float dz = static_cast<float>(trial % 3) * 0.25f / static_cast<float>(dict.width());
      std::vector<ClusterPoint> kept;
      for (auto p : pts) {
        if (rng() % 3 == 0) continue;
        p.z += dz;
        p.intensity += 25.0f * noise(rng);
        kept.push_back(p);
      }
      const DecodeResult r = decode_tag(kept, 1.0, dict, DecodeOptions{}, ws);
      ASSERT_GE(r.function, 0) << name;
      ASSERT_EQ(ws.evidence.size(), cells);
      double total = 0.0;
      for (float e : ws.evidence) total += std::fabs(e);
      int best = -1, second = -1;
      double s1 = -1e30, s2 = -1e30;
      for (int f = 0; f < dict.functions(); ++f) {
        double s = 0.0;
        for (size_t i = 0; i < cells; ++i) s += dict.signs(f)[i] * ws.evidence[i];
        if (s > s1) {
          s2 = s1;
          second = best;
          s1 = s;
          best = f;
        } else if (s > s2) {
          s2 = s;
          second = f;
        }
      }
      // Exact ties between different functions (symmetric codes) may order either way.
      if (std::fabs(s1 - s2) > 1e-5 * total) {
        EXPECT_EQ(r.function, best) << name << " trial " << trial;
      }
      EXPECT_NEAR(r.score, s1 / total, 1e-5) << name << " trial " << trial;
      EXPECT_NEAR(r.second_score, s2 / total, 1e-5) << name << " trial " << trial;
      if (r.second_function != second) {
        EXPECT_NEAR(r.second_score, s2 / total, 1e-6) << "a tie, else the wrong runner-up";
      }
    }
  }
}

// Each cell's evidence is eqs. (19), (21), (22) summed directly over the template samples in the
// cell and the points whose kernel reaches them, white minus black: what the separable products,
// the ratio recurrence and the vectorised exponentials compute. The defaults (2 samples per cell,
// a reach of 2 samples) take the straight-line path; 3 samples per cell, or a longer length scale
// (a reach of 3 samples), the general one.
TEST(RkhsDecoder, CellEvidenceIsTheKernelSumOverEachCellsSamples) {
  std::mt19937 rng(23);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::vector<ClusterPoint> pts;
  DecodeWorkspace ws;
  DecodeOptions three_samples, long_kernel;
  three_samples.samples_per_cell = 3;
  long_kernel.length_scale_cells = 0.4;
  for (const auto& [path, opt] :
       {std::pair{"defaults", DecodeOptions{}}, std::pair{"3 samples per cell", three_samples},
        std::pair{"length scale 0.4 cells", long_kernel}}) {
    for (const char* family : {"tag16h5", "tag25h9", "tag36h11"}) {
      const std::string name = std::string(family) + ", " + path;
      const RkhsDictionary dict(tags::builtin_family(family));
      const int W = dict.width(), S = opt.samples_per_cell, N = W * S;
      synth(dict.family(), 3, 1, {}, 3, pts);
      for (auto& p : pts) {  // off the plane, off the grid, noisy, some off the tag
        p.x += 0.02f * noise(rng);
        p.y = p.y * 1.1f + 0.01f * noise(rng);
        p.z += 0.3f / static_cast<float>(W);
        p.intensity += 20.0f * noise(rng);
      }
      prepare_decode(pts, intensity_levels(pts, ws), 1.0, ws);
      ASSERT_GE(decode_prepared(dict, opt, ws).function, 0) << name;
      const double sigma = opt.length_scale_cells / W, inv2s2 = 1.0 / (2 * sigma * sigma);
      const double lift = opt.lift_cells / W;
      const double inv2li = 1.0 / (2 * opt.intensity_length_scale * opt.intensity_length_scale);
      const int reach = static_cast<int>(std::ceil(3 * sigma * N));
      std::vector<double> direct(static_cast<size_t>(W * W), 0.0);
      for (const DecodePoint& p : ws.prepared) {
        const double xl = p.xn + lift * p.label;
        const double fc = (p.yn + 0.5) * N - 0.5, fr = (0.5 - p.zn) * N - 0.5;
        const int ic = static_cast<int>(std::floor(fc)), ir = static_cast<int>(std::floor(fr));
        for (int jr = std::max(0, ir - reach); jr <= std::min(N - 1, ir + reach + 1); ++jr)
          for (int jc = std::max(0, ic - reach); jc <= std::min(N - 1, ic + reach + 1); ++jc) {
            const double d2 = ((jc - fc) * (jc - fc) + (jr - fr) * (jr - fr)) / (N * N) * inv2s2;
            const double white = std::exp(-d2 - (xl - lift) * (xl - lift) * inv2s2 -
                                          (p.label - 1) * (p.label - 1) * inv2li);
            const double black = std::exp(-d2 - xl * xl * inv2s2 - p.label * p.label * inv2li);
            direct[static_cast<size_t>((jr / S) * W + jc / S)] += white - black;
          }
      }
      double largest = 0.0;
      for (double d : direct) largest = std::max(largest, std::fabs(d));
      ASSERT_GT(largest, 1.0) << name;
      for (size_t i = 0; i < direct.size(); ++i)
        EXPECT_NEAR(ws.evidence[i], direct[i], 2e-6 * largest) << name << " cell " << i;
    }
  }
}

// The cells that tell functions apart are the payload; the white ring and the black border are
// common to every function.
// The margin also counts the kernel tails that a cell without returns gets from its neighbours;
// seen_cells_lead asks the cells that hold returns alone.
TEST(RkhsDecoder, SeenCellsLeadAsksOnlyTheCellsWithReturns) {
  const auto& fam = tags::builtin_family("tag16h5");
  const RkhsDictionary dict(fam);
  DecodeWorkspace ws;
  const DecodeOptions opt;
  // Code a fully seen: it leads every other function on the seen cells.
  std::vector<ClusterPoint> pts;
  synth(fam, 0, 0, {}, 3, pts);
  DecodeResult r = decode_tag(pts, 1.0, dict, opt, ws);
  ASSERT_EQ(r.function, 0);
  std::vector<float> votes, counts;
  cell_votes(ws.prepared, dict.width(), opt.vote_inset_cells, votes, counts);
  EXPECT_GT(seen_cells_lead(dict, 0, votes, counts, opt, ws), 0.0);
  // The nearest other code (rotation 0): no returns in the cells where the two differ but one,
  // and that one shows b's colour.
  int b = -1, best_distance = 1 << 30;
  const int W = dict.width();
  for (int k = 1; k < fam.ncodes(); ++k) {
    int d = 0;
    for (int i = 0; i < W * W; ++i) d += dict.signs(0)[i] != dict.signs(4 * k)[i] ? 1 : 0;
    if (d < best_distance) {
      best_distance = d;
      b = k;
    }
  }
  ASSERT_GE(b, 1);
  std::vector<int> differ;
  for (int i = 0; i < W * W; ++i)
    if (dict.signs(0)[i] != dict.signs(4 * b)[i]) differ.push_back(i);
  ASSERT_GE(differ.size(), 2u);
  std::vector<ClusterPoint> seen;
  for (auto p : pts) {
    const int c = static_cast<int>((p.y + 0.5) * W), row = static_cast<int>((0.5 - p.z) * W);
    const int cell = row * W + c;
    if (cell == differ[0]) {
      p.intensity = dict.signs(4 * b)[cell] > 0 ? 200.0f : 30.0f;  // b's colour
    } else if (std::find(differ.begin(), differ.end(), cell) != differ.end()) {
      continue;  // not seen
    }
    seen.push_back(p);
  }
  r = decode_tag(seen, 1.0, dict, opt, ws);
  ASSERT_GE(r.function, 0);
  cell_votes(ws.prepared, W, opt.vote_inset_cells, votes, counts);
  EXPECT_LT(seen_cells_lead(dict, 0, votes, counts, opt, ws), 0.0)
      << "a fits the seen cells worse than b";
  EXPECT_GE(seen_cells_lead(dict, 4 * b, votes, counts, opt, ws), 0.0)
      << "nothing fits them better than b";
}

TEST(RkhsDecoder, VaryingCellsAreThePayload) {
  for (const char* name : {"tag16h5", "tag25h9", "tag36h11"}) {
    const auto& fam = tags::builtin_family(name);
    const RkhsDictionary dict(fam);
    const int w = fam.total_width, b = fam.border_start() + 1, pw = fam.payload_width();
    std::vector<int> payload;
    for (int r = b; r < b + pw; ++r)
      for (int c = b; c < b + pw; ++c) payload.push_back(r * w + c);
    EXPECT_EQ(dict.varying_cells(), payload) << name;
    ASSERT_EQ(dict.chunk_count(), (payload.size() + 7) / 8);
    for (int f = 0; f < dict.functions(); f += 7)
      for (size_t k = 0; k < payload.size(); ++k)
        EXPECT_EQ(dict.varying_sign(f, k), dict.signs(f)[payload[k]]);
  }
}

// Per-scan paths do not allocate in steady state: once grown, the workspace serves families of
// different sizes decoded in turn without a heap allocation (counted by operator new below).
TEST(RkhsDecoder, DecodingDoesNotAllocateOnceTheWorkspaceHasGrown) {
  std::vector<RkhsDictionary> dicts;
  for (const char* name : {"tag36h11", "tag16h5", "tag25h9"})
    dicts.emplace_back(tags::builtin_family(name));
  std::vector<std::vector<ClusterPoint>> pts(dicts.size());
  for (size_t k = 0; k < dicts.size(); ++k) synth(dicts[k].family(), 1, 0, {}, 2, pts[k]);
  DecodeWorkspace ws;
  for (size_t k = 0; k < dicts.size(); ++k)
    ASSERT_EQ(decode_tag(pts[k], 1.0, dicts[k], DecodeOptions{}, ws).rejection, Rejection::kNone);
  std::array<DecodeResult, 9> results;
  const long before = testing::heap_allocations();
  for (size_t i = 0; i < results.size(); ++i)
    results[i] = decode_tag(pts[i % 3], 1.0, dicts[i % 3], DecodeOptions{}, ws);
  const long during = testing::heap_allocations() - before;
  EXPECT_EQ(during, 0);
  for (const auto& r : results) {
    EXPECT_EQ(r.code_index, 1);
    EXPECT_EQ(r.rejection, Rejection::kNone);
  }
}

}  // namespace
}  // namespace lidartag::detector
