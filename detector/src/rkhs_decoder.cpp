#include "lidartag/detector/rkhs_decoder.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
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
}

namespace {

float median(std::vector<float>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

DecodeResult decode_tag(std::span<const ClusterPoint> points, double t, const RkhsDictionary& dict,
                        const DecodeOptions& opt, DecodeWorkspace& ws) {
  DecodeResult res;
  if (points.size() < 4 || t <= 0) return res;
  // Intensity labels: split around the mean, the median of each side is the black and the white
  // level (robust to a few specular or dark returns); labels are 0 for black, 1 for white.
  double mean = 0.0;
  for (const auto& p : points) mean += p.intensity;
  mean /= static_cast<double>(points.size());
  ws.sorted.clear();
  for (const auto& p : points)
    if (p.intensity < mean) ws.sorted.push_back(p.intensity);
  if (ws.sorted.empty()) return res;
  const float black = median(ws.sorted);
  ws.sorted.clear();
  for (const auto& p : points)
    if (p.intensity >= mean) ws.sorted.push_back(p.intensity);
  const float white = median(ws.sorted);
  if (white - black < opt.min_contrast) return res;

  const int W = dict.width();
  const int S = std::max(opt.samples_per_cell, 1);
  const int N = W * S;  // template sample points per axis
  const auto n2 = static_cast<size_t>(N * N);
  ws.acc_white.assign(n2, 0.0f);
  ws.acc_black.assign(n2, 0.0f);
  // Everything in units of the tag size: the dictionary does not depend on t.
  const double sigma = opt.length_scale_cells / W;
  const double inv2s2 = 1.0 / (2 * sigma * sigma);
  const double lift = opt.lift_cells / W;
  const double inv2li = 1.0 / (2 * opt.intensity_length_scale * opt.intensity_length_scale);
  const int reach = static_cast<int>(std::ceil(3 * sigma * N));
  ws.ex.resize(static_cast<size_t>(2 * reach + 2));
  ws.ez.resize(static_cast<size_t>(2 * reach + 2));
  for (const auto& p : points) {
    const double label = (p.intensity - black) / static_cast<double>(white - black);
    const double yn = p.y / t, zn = p.z / t;
    // 3-D lifting remark: the normal coordinate carries the intensity.
    const double xl = p.x / t + lift * label;
    // eq. (kernel) along the normal and eq. (kernel_intensity), against a white and a black
    // template point.
    const double ww =
        std::exp(-(xl - lift) * (xl - lift) * inv2s2 - (label - 1) * (label - 1) * inv2li);
    const double wb = std::exp(-xl * xl * inv2s2 - label * label * inv2li);
    // Sample j sits at (j + 0.5) / N - 0.5 across (y) and 0.5 - (j + 0.5) / N down (z).
    const double fc = (yn + 0.5) * N - 0.5, fr = (0.5 - zn) * N - 0.5;
    const int c0 = std::max(0, static_cast<int>(std::floor(fc)) - reach);
    const int c1 = std::min(N - 1, static_cast<int>(std::floor(fc)) + reach + 1);
    const int r0 = std::max(0, static_cast<int>(std::floor(fr)) - reach);
    const int r1 = std::min(N - 1, static_cast<int>(std::floor(fr)) + reach + 1);
    if (c0 > c1 || r0 > r1) continue;
    for (int c = c0; c <= c1; ++c) {
      const double d = (c - fc) / N;
      ws.ex[static_cast<size_t>(c - c0)] = static_cast<float>(std::exp(-d * d * inv2s2));
    }
    for (int r = r0; r <= r1; ++r) {
      const double d = (r - fr) / N;
      ws.ez[static_cast<size_t>(r - r0)] = static_cast<float>(std::exp(-d * d * inv2s2));
    }
    for (int r = r0; r <= r1; ++r) {
      const float kw = static_cast<float>(ww) * ws.ez[static_cast<size_t>(r - r0)];
      const float kb = static_cast<float>(wb) * ws.ez[static_cast<size_t>(r - r0)];
      float* aw = ws.acc_white.data() + static_cast<size_t>(r * N);
      float* ab = ws.acc_black.data() + static_cast<size_t>(r * N);
      for (int c = c0; c <= c1; ++c) {
        aw[c] += kw * ws.ex[static_cast<size_t>(c - c0)];
        ab[c] += kb * ws.ex[static_cast<size_t>(c - c0)];
      }
    }
  }
  // eq. (InnerProduct) against a template function is a sum over its sample points; per cell,
  // the white-minus-black evidence makes every code's inner product a signed sum over cells.
  const auto cells = static_cast<size_t>(W * W);
  ws.evidence.assign(cells, 0.0f);
  double total = 0.0;
  for (int r = 0; r < N; ++r)
    for (int c = 0; c < N; ++c) {
      const size_t s = static_cast<size_t>(r * N + c);
      ws.evidence[static_cast<size_t>((r / S) * W + c / S)] += ws.acc_white[s] - ws.acc_black[s];
    }
  // Mean evidence of a payload cell: the unit of the margin.
  double payload = 0.0;
  const int b0 = dict.family().border_start() + 1, pw = dict.family().payload_width();
  for (int r = b0; r < b0 + pw; ++r)
    for (int c = b0; c < b0 + pw; ++c)
      payload += std::fabs(ws.evidence[static_cast<size_t>(r * W + c)]);
  payload /= pw * pw;
  for (float e : ws.evidence) total += std::fabs(e);
  if (total <= 0.0 || payload <= 0.0) return res;

  const int nf = dict.functions();
  ws.scores.resize(static_cast<size_t>(nf));
  auto score_range = [&](int f0, int f1) {
    for (int f = f0; f < f1; ++f) {
      const float* s = dict.signs(f);
      float acc = 0.0f;
      for (size_t i = 0; i < cells; ++i) acc += s[i] * ws.evidence[i];
      ws.scores[static_cast<size_t>(f)] = acc;
    }
  };
  if (nf >= opt.parallel_min_functions)
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, 256),
                      [&](const tbb::blocked_range<int>& r) { score_range(r.begin(), r.end()); });
  else
    score_range(0, nf);
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
  res.function = best;
  res.code_index = best / 4;
  res.quarter_turns = best % 4;
  res.score = s1 / total;
  res.second_function = nf > 1 ? second : -1;
  res.second_score = nf > 1 ? s2 / total : -1.0;
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

}  // namespace lidartag::detector
