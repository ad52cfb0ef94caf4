#include "lidartag/detector/rkhs_decoder.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>

namespace lidartag::detector {

RkhsDictionary::RkhsDictionary(const tags::TagFamily& family)
    : family_(family), width_(family.total_width) {
  const auto w = static_cast<size_t>(width_);
  signs_.resize(family.codes.size() * 4 * w * w);
  std::vector<uint8_t> img, rot(w * w);
  for (size_t k = 0; k < family.codes.size(); ++k) {
    img = family.render(family.codes[k]);
    for (size_t q = 0; q < 4; ++q) {
      float* out = signs_.data() + (4 * k + q) * w * w;
      for (size_t i = 0; i < w * w; ++i) out[i] = img[i] ? 1.0f : -1.0f;
      // Turn the image clockwise: the cell (r, c) moves to (c, W-1-r).
      for (size_t r = 0; r < w; ++r)
        for (size_t c = 0; c < w; ++c) rot[c * w + (w - 1 - r)] = img[r * w + c];
      img.swap(rot);
    }
  }
  // The cells that tell functions apart; the others (white ring, black border) add the same to
  // every score.
  const int nf = functions();
  for (size_t i = 0; i < w * w; ++i) {
    bool same = true;
    for (int f = 1; f < nf && same; ++f) same = signs(f)[i] == signs(0)[i];
    if (!same) varying_.push_back(static_cast<int>(i));
  }
  chunks_.assign(static_cast<size_t>(nf) * chunk_count(), 0);
  for (int f = 0; f < nf; ++f)
    for (size_t k = 0; k < varying_.size(); ++k)
      if (signs(f)[varying_[k]] > 0)
        chunks_[static_cast<size_t>(f) * chunk_count() + k / 8] |=
            static_cast<uint8_t>(1U << (k % 8));
}

namespace {

// floor() without the library call, for arguments well within int range.
int floor_int(double v) {
  const int i = static_cast<int>(v);
  return v < i ? i - 1 : i;
}

float median(std::vector<float>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The element at index k of the sorted values a histogram of whole numbers 0-255 counts.
float histogram_element(const std::array<uint32_t, 256>& counts, size_t k) {
  size_t seen = 0;
  for (size_t v = 0; v < counts.size(); ++v) {
    seen += counts[v];
    if (seen > k) return static_cast<float>(v);
  }
  return 255.0f;
}

}  // namespace

IntensityLevels intensity_levels(std::span<const ClusterPoint> points, DecodeWorkspace& ws) {
  IntensityLevels lv;
  if (points.empty()) return lv;
  // Split around the mean, the median of each side is the black and the white level (robust to a
  // few specular or dark returns).
  double mean = 0.0;
  bool bytes = true;  // every intensity a whole number in [0, 255], as a Velodyne reports them
  for (const auto& p : points) {
    mean += p.intensity;
    bytes = bytes && p.intensity >= 0.0f && p.intensity <= 255.0f &&
            static_cast<float>(static_cast<int>(p.intensity)) == p.intensity;
  }
  mean /= static_cast<double>(points.size());
  if (bytes) {
    // The same medians from a histogram of each side: no sorting.
    // Indexed by side rather than branched on: a tag's points alternate between its colours.
    std::array<std::array<uint32_t, 256>, 2> counts{};
    size_t n_below = 0;
    for (const auto& p : points) {
      const bool low = p.intensity < mean;
      ++counts[low ? 0 : 1][static_cast<size_t>(p.intensity)];
      n_below += low ? 1 : 0;
    }
    const auto &below = counts[0], &above = counts[1];
    if (n_below == 0) return lv;
    lv.black = histogram_element(below, n_below / 2);
    lv.white = histogram_element(above, (points.size() - n_below) / 2);
    lv.valid = true;
    return lv;
  }
  ws.sorted.clear();
  for (const auto& p : points)
    if (p.intensity < mean) ws.sorted.push_back(p.intensity);
  if (ws.sorted.empty()) return lv;
  lv.black = median(ws.sorted);
  ws.sorted.clear();
  for (const auto& p : points)
    if (p.intensity >= mean) ws.sorted.push_back(p.intensity);
  lv.white = median(ws.sorted);
  lv.valid = true;
  return lv;
}

DecodeResult decode_tag(std::span<const ClusterPoint> points, double t, const RkhsDictionary& dict,
                        const DecodeOptions& opt, DecodeWorkspace& ws) {
  if (points.size() < 4 || t <= 0) return DecodeResult{};
  return decode_tag(points, intensity_levels(points, ws), t, dict, opt, ws);
}

void prepare_decode(std::span<const ClusterPoint> points, const IntensityLevels& levels, double t,
                    DecodeWorkspace& ws) {
  ws.prepared.clear();
  ws.widths = 0;
  ws.levels = levels;
  ws.prepared_ok = points.size() >= 4 && t > 0 && levels.valid;
  if (!ws.prepared_ok) return;
  // Intensity labels: 0 for black, 1 for white. Coordinates in units of the tag size: the
  // dictionary does not depend on t.
  const float black = levels.black, white = levels.white;
  for (const auto& p : points)
    ws.prepared.push_back(
        {p.x / t, p.y / t, p.z / t, (p.intensity - black) / static_cast<double>(white - black)});
}

DecodeResult decode_tag(std::span<const ClusterPoint> points, const IntensityLevels& levels,
                        double t, const RkhsDictionary& dict, const DecodeOptions& opt,
                        DecodeWorkspace& ws) {
  prepare_decode(points, levels, t, ws);
  return decode_prepared(dict, opt, ws);
}

namespace {

// e^x in float to about 1e-7 relative, without branches or calls, so that a loop over many
// arguments is vectorised: x = n ln 2 + r with |r| <= ln 2 / 2 (ln 2 in two parts, so that r is
// exact), e^r by its Taylor series to degree 7 (remainder below 1e-8), 2^n in the exponent bits.
// Arguments are clamped to [-87, 88], where the result stays a normal float (NaN to -87: the
// integer conversion below must not see it).
inline float exp_float(float x) {
  x = std::min(88.0f, std::max(-87.0f, x));
  const float n = (x * 1.44269504f + 12582912.0f) - 12582912.0f;  // round(x / ln 2)
  const float r = (x - n * 0.693359375f) + n * 2.12194440e-4f;
  float e = 1.0f / 5040.0f;  // Horner: 1 + r + r^2 / 2 + ... + r^7 / 7!
  e = e * r + 1.0f / 720.0f;
  e = e * r + 1.0f / 120.0f;
  e = e * r + 1.0f / 24.0f;
  e = e * r + 1.0f / 6.0f;
  e = e * r + 0.5f;
  e = e * r + 1.0f;
  e = e * r + 1.0f;
  return e * std::bit_cast<float>((static_cast<int>(n) + 127) << 23);
}

// Where point p's kernel reaches: the sample columns c0-c1 and rows r0-r1 (fc, fr its position in
// sample steps); false when it reaches no sample.
struct Reach {
  double fc, fr;
  int c0, c1, r0, r1;
};
inline bool reach_of(const DecodePoint& p, int N, int reach, Reach& out) {
  // Sample j sits at (j + 0.5) / N - 0.5 across (y) and 0.5 - (j + 0.5) / N down (z).
  out.fc = (p.yn + 0.5) * N - 0.5;
  out.fr = (0.5 - p.zn) * N - 0.5;
  if (!(std::fabs(out.fc) <= 4.0 * N && std::fabs(out.fr) <= 4.0 * N)) return false;  // far off
  const int ic = floor_int(out.fc), ir = floor_int(out.fr);
  out.c0 = std::max(0, ic - reach);
  out.c1 = std::min(N - 1, ic + reach + 1);
  out.r0 = std::max(0, ir - reach);
  out.r1 = std::min(N - 1, ir + reach + 1);
  return out.c0 <= out.c1 && out.r0 <= out.r1;
}

// The evidence accumulator's rows are kPad cells longer, and it has kPad more rows, than the
// template: a point's kernel is added to a fixed 4 x 4 block of cells, whatever of it lies past
// the template's edge landing in the padding.
constexpr int kPad = 3;

// Every point's kernel, weighed by its white-minus-black factor, into the cells it reaches (ws.acc,
// stride W + kPad), for any samples per cell S: per axis the sum of its samples' factors in each
// cell, then their products (the kernel is separable).
void accumulate_any(int W, int S, double ratio_step, DecodeWorkspace& ws) {
  const size_t n = ws.prepared.size();
  const float *arg_w = ws.exps.data(), *arg_b = arg_w + n, *arg_c = arg_b + n, *arg_r = arg_c + n;
  const auto stride = static_cast<size_t>(W + kPad);
  // Per cell along one axis, the sum of the factors of its samples in reach; returns the cells.
  auto cell_factors = [&](int j0, int j1, double ratio, std::vector<double>& out) {
    double g = 1.0;
    size_t m = 0;
    int left = (j0 / S + 1) * S - j0;  // samples of the first cell in reach
    out[0] = 0.0;
    for (int j = j0; j <= j1; ++j) {
      out[m] += g;
      g *= ratio;
      ratio *= ratio_step;
      if (--left == 0 && j < j1) {
        out[++m] = 0.0;
        left = S;
      }
    }
    return m + 1;
  };
  for (size_t i = 0; i < n; ++i) {
    const auto [c0, c1, r0, r1] = ws.reach[i];
    if (c0 < 0) continue;
    const size_t ncol = cell_factors(c0, c1, arg_c[i], ws.ex);
    const size_t nrow = cell_factors(r0, r1, arg_r[i], ws.ez);
    const double k = static_cast<double>(arg_w[i]) - static_cast<double>(arg_b[i]);
    for (size_t r = 0; r < nrow; ++r) {
      const double kr = k * ws.ez[r];
      double* out = ws.acc.data() + static_cast<size_t>(r0 / S) * stride +
                    static_cast<size_t>(c0 / S) + r * stride;
      for (size_t c = 0; c < ncol; ++c) out[c] += kr * ws.ex[c];
    }
  }
}

// accumulate_any for 2 samples per cell and a reach of at most 2 samples (the defaults): at most
// 6 samples, so 4 cells, per axis, in straight-line code. The 6 factors from the first sample on
// (zero past the last one in reach), paired into cells by the first sample's parity, and the 4 x 4
// block added whole (zeros past the point's last cell): the same sums in the same order as
// accumulate_any's (0 + g = g), without its loops' mispredicted exits and stores to the stack.
void accumulate_two_samples(int W, double ratio_step, DecodeWorkspace& ws) {
  const size_t n = ws.prepared.size();
  const float *arg_w = ws.exps.data(), *arg_b = arg_w + n, *arg_c = arg_b + n, *arg_r = arg_c + n;
  const auto stride = static_cast<size_t>(W + kPad);
  // Cell m = kA[m] + kB[m] of {0, g0, ..., g5, 0}: samples (0, 1), (2, 3), (4, 5) from an even
  // first sample; 0, (1, 2), (3, 4), 5 from an odd one.
  static constexpr std::array<std::array<uint8_t, 4>, 2> kA = {{{1, 3, 5, 0}, {1, 2, 4, 6}}};
  static constexpr std::array<std::array<uint8_t, 4>, 2> kB = {{{2, 4, 6, 0}, {0, 3, 5, 0}}};
  auto cell_factors = [ratio_step](int j0, int j1, double ratio, std::array<double, 4>& out) {
    // kKeep[j1 - j0][k]: 1 for the samples in reach, 0 past them (f * 1 and f * 0 are exact; a
    // comparison here became a branch on the window's length).
    static constexpr std::array<std::array<double, 6>, 6> kKeep = {{{1, 0, 0, 0, 0, 0},
                                                                    {1, 1, 0, 0, 0, 0},
                                                                    {1, 1, 1, 0, 0, 0},
                                                                    {1, 1, 1, 1, 0, 0},
                                                                    {1, 1, 1, 1, 1, 0},
                                                                    {1, 1, 1, 1, 1, 1}}};
    const auto& keep = kKeep[static_cast<size_t>(j1 - j0)];
    std::array<double, 8> g{};
    double f = 1.0;
    for (size_t k = 0; k < 6; ++k) {
      g[k + 1] = f * keep[k];
      f *= ratio;
      ratio *= ratio_step;
    }
    const auto& ia = kA[static_cast<size_t>(j0 & 1)];
    const auto& ib = kB[static_cast<size_t>(j0 & 1)];
    for (size_t m = 0; m < 4; ++m) out[m] = g[ia[m]] + g[ib[m]];
  };
  std::array<double, 4> fx{}, fz{};
  for (size_t i = 0; i < n; ++i) {
    const auto [c0, c1, r0, r1] = ws.reach[i];
    if (c0 < 0) continue;
    cell_factors(c0, c1, arg_c[i], fx);
    cell_factors(r0, r1, arg_r[i], fz);
    const double k = static_cast<double>(arg_w[i]) - static_cast<double>(arg_b[i]);
    double* out =
        ws.acc.data() + static_cast<size_t>(r0 >> 1) * stride + static_cast<size_t>(c0 >> 1);
    for (size_t r = 0; r < 4; ++r, out += stride) {
      const double kr = k * fz[r];
      for (size_t c = 0; c < 4; ++c) out[c] += kr * fx[c];
    }
  }
}

// eq. (18) against a template function is a sum over its sample points; per cell of a
// W x W template, the white-minus-black kernel sums of the prepared points make every code's inner
// product a signed sum over cells. Fills `evidence` (W x W, row-major) and returns the sum of its
// magnitudes.
double accumulate_evidence(int W, const DecodeOptions& opt, DecodeWorkspace& ws,
                           std::vector<float>& evidence) {
  const int S = std::max(opt.samples_per_cell, 1);
  const int N = W * S;  // template sample points per axis
  const auto cells_w = static_cast<size_t>(W);
  const auto cells = cells_w * cells_w;
  ws.acc.assign(static_cast<size_t>(W + kPad) * static_cast<size_t>(W + kPad), 0.0);
  // Everything in units of the tag size: the dictionary does not depend on t.
  const double sigma = opt.length_scale_cells / W;
  const double inv2s2 = 1.0 / (2 * sigma * sigma);
  const double lift = opt.lift_cells / W;
  const double inv2li = 1.0 / (2 * opt.intensity_length_scale * opt.intensity_length_scale);
  const int reach = static_cast<int>(std::ceil(3 * sigma * N));
  // The spatial kernel between a point and the sample at index j (in sample steps) is
  // exp(-a (j - f)^2): starting from the first sample j0 of the reach, its factor is
  // exp(-a (j0 - f)^2) times prod of ratios exp(-a (2 (j - f) + 1)), each ratio the previous one
  // times exp(-2 a). Two exponentials per axis instead of one per sample.
  const double a = inv2s2 / (static_cast<double>(N) * N);
  const double ratio_step = std::exp(-2 * a);
  ws.ex.resize(static_cast<size_t>(2 * reach + 2));
  ws.ez.resize(static_cast<size_t>(2 * reach + 2));
  // Per point four exponentials: eq. (19) along the normal and eq. (21), against a white and a
  // black template point, times the spatial kernel of the first sample in reach; and the first
  // ratio along each axis. Their arguments first, then all of them in one vectorised loop. Single
  // precision: the weights need no more than the float evidence they add to.
  const size_t n = ws.prepared.size();
  ws.exps.resize(4 * n);
  ws.reach.resize(n);
  float *arg_w = ws.exps.data(), *arg_b = arg_w + n, *arg_c = arg_b + n, *arg_r = arg_c + n;
  Reach q{};
  for (size_t i = 0; i < n; ++i) {
    const DecodePoint& p = ws.prepared[i];
    if (!reach_of(p, N, reach, q)) {
      arg_w[i] = arg_b[i] = arg_c[i] = arg_r[i] = 0.0f;
      ws.reach[i] = {-1, -1, -1, -1};
      continue;
    }
    ws.reach[i] = {q.c0, q.c1, q.r0, q.r1};
    // eq. (22), the 3-D lifting remark: the normal coordinate carries the intensity.
    const double label = p.label, xl = p.xn + lift * label;
    const double first = -a * ((q.c0 - q.fc) * (q.c0 - q.fc) + (q.r0 - q.fr) * (q.r0 - q.fr));
    arg_w[i] = static_cast<float>(first - (xl - lift) * (xl - lift) * inv2s2 -
                                  (label - 1) * (label - 1) * inv2li);
    arg_b[i] = static_cast<float>(first - xl * xl * inv2s2 - label * label * inv2li);
    arg_c[i] = static_cast<float>(-a * (2 * (q.c0 - q.fc) + 1));
    arg_r[i] = static_cast<float>(-a * (2 * (q.r0 - q.fr) + 1));
  }
  for (size_t i = 0; i < 4 * n; ++i) ws.exps[i] = exp_float(ws.exps[i]);
  if (S == 2 && reach <= 2) {
    accumulate_two_samples(W, ratio_step, ws);
  } else {
    accumulate_any(W, S, ratio_step, ws);
  }
  evidence.resize(cells);
  double total = 0.0;
  const auto stride = static_cast<size_t>(W + kPad);
  for (size_t r = 0; r < cells_w; ++r)
    for (size_t c = 0; c < cells_w; ++c) {
      const size_t i = r * cells_w + c;
      evidence[i] = static_cast<float>(ws.acc[r * stride + c]);
      total += std::fabs(evidence[i]);
    }
  return total;
}

// The varying cells' part of eq. (18) for every function of `dict` into ws.scores, from their
// evidence in ws.varying: in groups of 8, one entry per group of a table of the 256 sign patterns.
void score_functions(const RkhsDictionary& dict, const DecodeOptions& opt, DecodeWorkspace& ws) {
  const auto& vary = dict.varying_cells();
  const size_t groups = dict.chunk_count();
  ws.tables.resize(groups * 256);
  for (size_t g = 0; g < groups; ++g) {
    float* table = ws.tables.data() + g * 256;
    const size_t n = std::min<size_t>(8, vary.size() - 8 * g);
    table[0] = 0.0f;  // every cell black
    for (size_t i = 0; i < n; ++i) table[0] -= ws.varying[8 * g + i];
    for (unsigned m = 1; m < 256; ++m) {  // one more white cell than m without its lowest bit
      const unsigned low = static_cast<unsigned>(std::countr_zero(m));
      table[m] = low < n ? table[m & (m - 1)] + 2.0f * ws.varying[8 * g + low] : 0.0f;
    }
  }
  const int nf = dict.functions();
  ws.scores.resize(static_cast<size_t>(nf));
  auto score_range = [&](int f0, int f1) {
    const float* t = ws.tables.data();
    int f = f0;
    // Four functions at a time: four independent chains of additions instead of one (each
    // function's sum in the same order as alone).
    for (; f + 4 <= f1; f += 4) {
      const uint8_t *i0 = dict.chunks(f), *i1 = dict.chunks(f + 1), *i2 = dict.chunks(f + 2),
                    *i3 = dict.chunks(f + 3);
      float s0 = 0.0f, s1 = 0.0f, s2 = 0.0f, s3 = 0.0f;
      for (size_t g = 0; g < groups; ++g) {
        s0 += t[g * 256 + i0[g]];
        s1 += t[g * 256 + i1[g]];
        s2 += t[g * 256 + i2[g]];
        s3 += t[g * 256 + i3[g]];
      }
      float* out = ws.scores.data() + f;
      out[0] = s0;
      out[1] = s1;
      out[2] = s2;
      out[3] = s3;
    }
    for (; f < f1; ++f) {
      const uint8_t* idx = dict.chunks(f);
      float sum = 0.0f;
      for (size_t g = 0; g < groups; ++g) sum += t[g * 256 + idx[g]];
      ws.scores[static_cast<size_t>(f)] = sum;
    }
  };
  if (nf >= opt.parallel_min_functions) {
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, 1024),
                      [&](const tbb::blocked_range<int>& r) { score_range(r.begin(), r.end()); });
  } else {
    score_range(0, nf);
  }
}

}  // namespace

DecodeResult decode_prepared(const RkhsDictionary& dict, const DecodeOptions& opt,
                             DecodeWorkspace& ws) {
  DecodeResult res;
  if (!ws.prepared_ok) return res;
  if (ws.levels.white - ws.levels.black < opt.min_contrast) return res;

  const int W = dict.width();
  const auto cells = static_cast<size_t>(W) * static_cast<size_t>(W);
  // The evidence of this width, computed once per prepare_decode.
  DecodeWorkspace::Evidence* ev = nullptr;
  for (size_t i = 0; i < ws.widths; ++i)
    if (ws.by_width[i].width == W) ev = &ws.by_width[i];
  if (ev == nullptr) {
    ev = &ws.by_width[ws.widths < ws.by_width.size() ? ws.widths++ : ws.by_width.size() - 1];
    ev->width = W;
    ev->cells.reserve(256);  // any width up to 16: a slot that changes width never reallocates
    ev->total = accumulate_evidence(W, opt, ws, ev->cells);
  }
  ws.evidence.assign(ev->cells.begin(), ev->cells.end());
  const double total = ev->total;
  // Mean evidence of a payload cell: the unit of the margin.
  double payload = 0.0;
  const int b0 = dict.family().border_start() + 1, pw = dict.family().payload_width();
  for (int r = b0; r < b0 + pw; ++r)
    for (int c = b0; c < b0 + pw; ++c)
      payload += std::fabs(ws.evidence[static_cast<size_t>(r * W + c)]);
  payload /= pw * pw;
  if (total <= 0.0 || payload <= 0.0) return res;

  // eq. (18) of every function: the cells common to all functions add `common`; the
  // varying cells, in groups of 8, add one entry per group of a table of the 256 sign patterns.
  const auto& vary = dict.varying_cells();
  ws.varying.resize(vary.size());
  for (size_t k = 0; k < vary.size(); ++k)
    ws.varying[k] = ws.evidence[static_cast<size_t>(vary[k])];
  double common = 0.0;
  {
    const float* s0 = dict.signs(0);
    size_t k = 0;
    for (size_t i = 0; i < cells; ++i) {
      if (k < vary.size() && static_cast<size_t>(vary[k]) == i)
        ++k;
      else
        common += s0[i] * ws.evidence[i];
    }
  }
  score_functions(dict, opt, ws);
  const int nf = dict.functions();
  // Best and runner-up; of equal scores the first function.
  int best = 0, second = -1;
  float s1 = -1e30f, s2 = -1e30f;
  for (int f = 0; f < nf; ++f) {
    const float s = ws.scores[static_cast<size_t>(f)];
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
  ws.common = common;
  ws.total = total;
  ws.payload = payload;
  res.function = best;
  res.code_index = best / 4;
  res.quarter_turns = best % 4;
  res.score = (s1 + common) / total;
  res.second_function = nf > 1 ? second : -1;
  res.second_score = nf > 1 ? (s2 + common) / total : -1.0;
  // One cell flipped changes a score by twice that cell's evidence; in units of the mean payload
  // cell.
  res.cells_per_score = total / (2.0 * payload);
  res.margin_bits = nf > 1 ? (s1 - s2) / (2.0 * payload) : 1e9;
  if (res.score < opt.min_score)
    res.rejection = Rejection::kLowScore;
  else if (res.margin_bits < opt.min_margin_bits)
    res.rejection = Rejection::kAmbiguous;
  else
    res.rejection = Rejection::kNone;
  return res;
}

void normalised_scores(const DecodeWorkspace& ws, std::vector<float>& out) {
  out.resize(ws.scores.size());
  if (!(ws.total > 0.0)) {
    std::fill(out.begin(), out.end(), 0.0f);
    return;
  }
  // As DecodeResult::score is computed, so that the best function's entry equals it.
  for (size_t f = 0; f < ws.scores.size(); ++f)
    out[f] = static_cast<float>((ws.scores[f] + ws.common) / ws.total);
}

int vote_cell(double yn, double zn, int w, double inset) {
  const double fc = (yn + 0.5) * w, fr = (0.5 - zn) * w;
  if (!(fc >= 0.0 && fc < w && fr >= 0.0 && fr < w)) return -1;
  const int c = static_cast<int>(fc), r = static_cast<int>(fr);
  const double uc = fc - c, ur = fr - r;
  if (uc < inset || uc > 1.0 - inset || ur < inset || ur > 1.0 - inset) return -1;
  return r * w + c;
}

void cell_votes(std::span<const DecodePoint> prepared, int w, double inset,
                std::vector<float>& votes, std::vector<float>& counts) {
  const auto cells = static_cast<size_t>(w) * static_cast<size_t>(w);
  votes.assign(cells, 0.0f);
  counts.assign(cells, 0.0f);
  for (const auto& p : prepared) {
    const int i = vote_cell(p.yn, p.zn, w, inset);
    if (i < 0) continue;
    votes[static_cast<size_t>(i)] += point_vote(p.label);
    counts[static_cast<size_t>(i)] += 1.0f;
  }
}

double seen_cells_lead(const RkhsDictionary& dict, int function, std::span<const float> votes,
                       std::span<const float> counts, const DecodeOptions& opt,
                       DecodeWorkspace& ws) {
  const int W = dict.width();
  const int nf = dict.functions();
  const auto cells = static_cast<size_t>(W) * static_cast<size_t>(W);
  if (function < 0 || function >= nf || nf <= 1 || votes.size() != cells || counts.size() != cells)
    return 0.0;
  // Each cell's mean vote; 0 where no point lies well inside. Not the kernel evidence: that also
  // holds the neighbours' kernel tails, which can outweigh a single grey return in the cell.
  const auto& vary = dict.varying_cells();
  ws.varying.resize(vary.size());
  for (size_t k = 0; k < vary.size(); ++k) {
    const auto i = static_cast<size_t>(vary[k]);
    ws.varying[k] = counts[i] > 0.0f ? votes[i] / counts[i] : 0.0f;
  }
  score_functions(dict, opt, ws);
  float rival = -1e30f;
  for (int f = 0; f < nf; ++f)
    if (f != function) rival = std::max(rival, ws.scores[static_cast<size_t>(f)]);
  // Two functions' scores differ by twice the mean votes of the cells where they differ.
  return static_cast<double>(ws.scores[static_cast<size_t>(function)] - rival) / 2.0;
}

std::vector<RkhsDictionary> other_builtin_dictionaries(std::span<const std::string> configured) {
  std::vector<RkhsDictionary> out;
  for (const auto& name : tags::builtin_family_names())
    if (std::find(configured.begin(), configured.end(), name) == configured.end())
      out.emplace_back(tags::builtin_family(name));
  return out;
}

}  // namespace lidartag::detector
