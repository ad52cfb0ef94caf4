#include "lidartag/detector/edge_features.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>

namespace lidartag::detector {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

float dist(const Scan& s, size_t a, size_t b) {
  const float dx = s.x[a] - s.x[b], dy = s.y[a] - s.y[b], dz = s.z[a] - s.z[b];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// When both neighbours return and their ranges are close, neither distance of eq. (1) can exceed
// zeta (|p_j - p_i| <= |r_j - r_i| + r * angle between the beams): no square root needed. Written
// without branches so that the loop over a ring is vectorised; nearly every point is quiet.
inline bool quiet(float ri, float rl, float rr, float lateral, float zeta) {
  return (rl > 0.0f) & (rr > 0.0f) & (std::fabs(rl - ri) + lateral * std::max(rl, ri) <= zeta) &
         (std::fabs(rr - ri) + lateral * std::max(rr, ri) <= zeta);
}

// One ring of return 0.
struct Ring {
  const Scan& scan;
  const FeatureOptions& opt;
  size_t base;
  int cols;
  bool wraps;

  int wrap(int c) const { return c < 0 ? c + cols : (c >= cols ? c - cols : c); }

  // The neighbour l columns away in direction `step`, or the next return behind a short dropout.
  // Across a dropout the distance is the range difference: the lateral spacing grows with the gap,
  // the depth step of a real edge does not.
  bool neighbour(int c, int step, size_t& at, float& d) const {
    const size_t i = base + static_cast<size_t>(c);
    for (int k = 0; k <= opt.max_gap; ++k) {
      int cc = c + step * (opt.ell + k);
      if (wraps) {
        cc = wrap(cc);
      } else if (cc < 0 || cc >= cols) {
        return false;
      }
      at = base + static_cast<size_t>(cc);
      if (scan.valid(at)) {
        d = k == 0 ? dist(scan, at, i) : std::fabs(scan.range[at] - scan.range[i]);
        return true;
      }
    }
    return false;
  }

  // neighbour() for a column whose search window lies inside the ring: no wrap, no end test.
  bool neighbour_inside(int c, int step, size_t& at, float& d) const {
    const size_t i = base + static_cast<size_t>(c);
    const float* r = scan.range.data() + static_cast<std::ptrdiff_t>(i) + step * opt.ell;
    for (int k = 0; k <= opt.max_gap; ++k) {
      if (r[step * k] > 0.0f) {
        at = static_cast<size_t>(static_cast<std::ptrdiff_t>(i) + step * (opt.ell + k));
        d = k == 0 ? dist(scan, at, i) : std::fabs(scan.range[at] - scan.range[i]);
        return true;
      }
    }
    return false;
  }

  // The signed eq. (1) value at column c (a usable point that is not quiet) when it is an edge
  // point on the near side of its jump; 0 otherwise.
  float edge_value(int c) const {
    const size_t i = base + static_cast<size_t>(c);
    size_t il = 0, ir = 0;
    float dl = kInf, dr = kInf;
    const int span = opt.ell + opt.max_gap;
    const bool inside = c - span >= 0 && c + span < cols;
    const bool has_l = inside ? neighbour_inside(c, -1, il, dl) : neighbour(c, -1, il, dl);
    const bool has_r = inside ? neighbour_inside(c, 1, ir, dr) : neighbour(c, 1, ir, dr);
    if (!has_l && !has_r) return 0.0f;  // an isolated return: noise, not an edge
    // eq. (1): grad D = |p_{i+l} - p_i| - |p_{i-l} - p_i|.
    const float g = std::isinf(dr) ? kInf : std::isinf(dl) ? -kInf : dr - dl;
    if (std::fabs(g) <= opt.zeta_m) return 0.0f;
    // Keep the near side of the jump only: the feature lies on the foreground object.
    const bool jump_right = g > 0;
    const float other =
        jump_right ? (has_r ? scan.range[ir] : kInf) : (has_l ? scan.range[il] : kInf);
    return other > scan.range[i] ? g : 0.0f;
  }
};

}  // namespace

void detect_edge_features(const Scan& scan, const FeatureOptions& opt, float max_pair_chord_m,
                          std::vector<Feature>& out, std::vector<float>& edges) {
  out.clear();
  const int cols = scan.columns;
  const int ell = opt.ell;
  if (cols <= 2 * ell || ell < 1) return;
  const float lo_range = opt.min_range_m, hi_range = opt.max_range_m, zeta = opt.zeta_m;
  // A full rotation is a circle: the neighbours of the last column are the first ones.
  const bool wraps = rotation_wraps(scan);
  // Upper bound of the angle between the beams of l columns apart, radians (twice the mean step).
  const float lateral = 4.0f * static_cast<float>(std::numbers::pi) * static_cast<float>(ell) /
                        static_cast<float>(cols);
  for (int ring = 0; ring < scan.rings; ++ring) {
    const Ring rg{scan, opt, scan.at(0, ring, 0), cols, wraps};
    const float* range = scan.range.data() + rg.base;
    // The ring's edge points in column order, as (column, signed eq. (1) value) pairs.
    edges.clear();
    auto consider = [&](int c) {
      const float g = rg.edge_value(c);
      if (g != 0.0f) {
        edges.push_back(static_cast<float>(c));  // exact: columns are far below 2^24
        edges.push_back(g);
      }
    };
    auto usable = [&](float r) { return (r >= lo_range) & (r <= hi_range); };
    // The first and last l columns have their neighbours across the cut: only in a full rotation
    // (the ends of a partial rotation have one side only).
    auto check_end = [&](int c) {
      const float ri = range[c];
      if (usable(ri) && !quiet(ri, range[rg.wrap(c - ell)], range[rg.wrap(c + ell)], lateral, zeta))
        consider(c);
    };
    if (wraps)
      for (int c = 0; c < ell; ++c) check_end(c);
    // The interior in blocks: the quiet test for a whole block at once, then the few candidates.
    constexpr int kBlock = 16;
    int c = ell;
    for (; c + kBlock <= cols - ell; c += kBlock) {
      const float* p = range + c;
      std::array<uint8_t, kBlock> cand;
      for (int l = 0; l < kBlock; ++l)
        cand[static_cast<size_t>(l)] = static_cast<uint8_t>(
            usable(p[l]) & !quiet(p[l], p[l - ell], p[l + ell], lateral, zeta));
      // Each candidate is one set bit (bit 0 of its byte): visit them by their bit positions.
      for (int half = 0; half < 2; ++half) {
        uint64_t w = 0;
        std::memcpy(&w, cand.data() + 8 * half, 8);
        for (; w != 0; w &= w - 1) consider(c + 8 * half + std::countr_zero(w) / 8);
      }
    }
    for (; c < cols - ell; ++c)
      if (usable(range[c]) && !quiet(range[c], range[c - ell], range[c + ell], lateral, zeta))
        consider(c);
    if (wraps)
      for (c = cols - ell; c < cols; ++c) check_end(c);

    // The "one edge among n+1 consecutive points" rule: an edge point is a feature when some
    // window of n+1 consecutive columns holds it and no other edge point, i.e. when the gaps to
    // the previous (a) and next (b) edge points satisfy a + b >= n + 2. The walk starts just after
    // a surface ends so that a run across the start of the rotation stays whole.
    const size_t m = edges.size() / 2;
    if (m == 0) continue;
    auto col_of = [&](size_t e) { return static_cast<int>(edges[2 * e]); };
    auto g_of = [&](size_t e) { return edges[2 * e + 1]; };
    int start = 0;     // the walk's first column
    size_t first = 0;  // the walk's first edge
    if (wraps) {
      size_t e = 0;
      while (e < m && g_of(e) <= 0.0f) ++e;  // the first column where a surface ends
      if (e < m) {
        start = col_of(e) + 1;
        first = e + 1 < m ? e + 1 : 0;
      }
    }
    // Position of an edge along the walk.
    auto pos = [&](size_t e) {
      const int k = col_of(e) - start;
      return k < 0 ? k + cols : k;
    };
    int prev_edge = -1'000'000;
    int run_start_feature = -1;  // the side -1 feature that opened the current continuous run
    for (size_t step = 0; step < m; ++step) {
      const size_t e = (first + step) % m;
      const int k = pos(e);
      // The next edge along the walk; in a full rotation the walk continues into its beginning.
      int next = 1'000'000;
      if (step + 1 < m)
        next = pos((e + 1) % m);
      else if (wraps)
        next = pos(first) + cols;
      const int next_edge = next - k <= opt.n + 1 ? next : 1'000'000;
      const int a = k - prev_edge, b = next_edge - k;
      const float g = g_of(e);
      const int8_t side = g > 0 ? int8_t{1} : int8_t{-1};
      if (static_cast<long>(a) + b >= opt.n + 2) {
        const int col = col_of(e);
        const size_t i = rg.base + static_cast<size_t>(col);
        Feature f;
        f.ring = ring;
        f.col = col;
        f.x = scan.x[i];
        f.y = scan.y[i];
        f.z = scan.z[i];
        f.range = scan.range[i];
        f.side = side;
        if (side > 0 && run_start_feature >= 0 && max_pair_chord_m > 0.0f) {
          const Feature& s = out[static_cast<size_t>(run_start_feature)];
          const float dx = s.x - f.x, dy = s.y - f.y, dz = s.z - f.z;
          if (dx * dx + dy * dy + dz * dz <= max_pair_chord_m * max_pair_chord_m)
            f.partner = run_start_feature;
        }
        out.push_back(f);
        run_start_feature = side < 0 ? static_cast<int>(out.size()) - 1 : -1;
      } else {
        run_start_feature = -1;  // a run broken by an edge that is not a feature
      }
      prev_edge = k;
    }
  }
}

bool rotation_wraps(const Scan& scan) {
  if (scan.columns < 3) return false;
  const auto n = static_cast<size_t>(scan.columns);
  const double span = scan.column_azimuth_deg[n - 1] - scan.column_azimuth_deg[0];
  const double covered = span < 0 ? span + 360.0 : span;
  const double step = covered / static_cast<double>(n - 1);
  return 360.0 - covered <= 2.5 * step;  // the gap from the last column to the first is one step
}

}  // namespace lidartag::detector
