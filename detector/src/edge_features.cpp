#include "lidartag/detector/edge_features.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace lidartag::detector {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

float dist(const Scan& s, size_t a, size_t b) {
  const float dx = s.x[a] - s.x[b], dy = s.y[a] - s.y[b], dz = s.z[a] - s.z[b];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace

void detect_edge_features(const Scan& scan, const FeatureOptions& opt, std::vector<Feature>& out,
                          std::vector<float>& grad) {
  out.clear();
  const int cols = scan.columns;
  if (cols <= 2 * opt.ell || opt.ell < 1) return;
  grad.resize(static_cast<size_t>(cols));
  auto usable = [&](size_t i) {
    return scan.range[i] >= opt.min_range_m && scan.range[i] <= opt.max_range_m;
  };
  // A full rotation is a circle: the neighbours of the last column are the first ones.
  const bool wraps = rotation_wraps(scan);
  // Upper bound of the angle between the beams of l columns apart, radians (twice the mean step).
  const float lateral = 4.0f * static_cast<float>(std::numbers::pi) * static_cast<float>(opt.ell) /
                        static_cast<float>(cols);
  auto wrap = [&](int c) { return c < 0 ? c + cols : (c >= cols ? c - cols : c); };
  for (int ring = 0; ring < scan.rings; ++ring) {
    const size_t base = scan.at(0, ring, 0);
    // grad[c] = signed eq. (GD) value where c is an edge point, 0 elsewhere.
    int first_end = -1;  // a column where a surface ends: no run is open just after it
    for (int c = 0; c < cols; ++c) {
      const size_t i = base + static_cast<size_t>(c);
      grad[static_cast<size_t>(c)] = 0.0f;
      if (!usable(i)) continue;
      if (!wraps && (c - opt.ell < 0 || c + opt.ell >= cols))
        continue;  // the ends of a partial rotation have one side only
      // Fast path: when both neighbours return and their ranges are close, neither distance of
      // eq. (GD) can exceed zeta (|p_j - p_i| <= |r_j - r_i| + r * angle between the beams).
      {
        const size_t jl = base + static_cast<size_t>(wrap(c - opt.ell));
        const size_t jr = base + static_cast<size_t>(wrap(c + opt.ell));
        const float ri = scan.range[i], rl = scan.range[jl], rr = scan.range[jr];
        if (rl > 0.0f && rr > 0.0f &&
            std::fabs(rl - ri) + lateral * std::max(rl, ri) <= opt.zeta_m &&
            std::fabs(rr - ri) + lateral * std::max(rr, ri) <= opt.zeta_m)
          continue;
      }
      // The neighbour l columns away, or the next return behind a short dropout. Across a dropout
      // the distance is the range difference: the lateral spacing grows with the gap, the depth
      // step of a real edge does not.
      auto neighbour = [&](int step, size_t& at, float& d) {
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
      };
      size_t il = 0, ir = 0;
      float dl = kInf, dr = kInf;
      const bool has_l = neighbour(-1, il, dl), has_r = neighbour(1, ir, dr);
      if (!has_l && !has_r) continue;  // an isolated return: noise, not an edge
      // eq. (GD): grad D = |p_{i+l} - p_i| - |p_{i-l} - p_i|.
      const float g = std::isinf(dr) ? kInf : std::isinf(dl) ? -kInf : dr - dl;
      if (std::fabs(g) <= opt.zeta_m) continue;
      // Keep the near side of the jump only: the feature lies on the foreground object.
      const bool jump_right = g > 0;
      const float other =
          jump_right ? (has_r ? scan.range[ir] : kInf) : (has_l ? scan.range[il] : kInf);
      if (other > scan.range[i]) {
        grad[static_cast<size_t>(c)] = g;
        if (g > 0 && first_end < 0) first_end = c;
      }
    }
    // The "one edge among n+1 consecutive points" rule: an edge point is a feature when some
    // window of n+1 consecutive columns holds it and no other edge point, i.e. when the gaps to
    // the previous (a) and next (b) edge points satisfy a + b >= n + 2. The walk starts just after
    // a surface ends so that a run across the start of the rotation stays whole.
    const int start = wraps && first_end >= 0 ? first_end + 1 : 0;
    int prev_edge = -1'000'000;
    int run_start_feature = -1;  // the side -1 feature that opened the current continuous run
    for (int k = 0; k < cols; ++k) {
      const int c = wraps ? wrap(start + k) : k;
      const float g = grad[static_cast<size_t>(c)];
      if (g == 0.0f) continue;
      int next_edge = 1'000'000;
      for (int j = k + 1; j <= k + opt.n + 1 && (wraps || j < cols); ++j)
        if (grad[static_cast<size_t>(wraps ? wrap(start + j) : j)] != 0.0f) {
          next_edge = j;
          break;
        }
      const int a = k - prev_edge, b = next_edge - k;
      const int8_t side = g > 0 ? int8_t{1} : int8_t{-1};
      if (static_cast<long>(a) + b >= opt.n + 2) {
        const size_t i = base + static_cast<size_t>(c);
        Feature f;
        f.ring = ring;
        f.col = c;
        f.x = scan.x[i];
        f.y = scan.y[i];
        f.z = scan.z[i];
        f.range = scan.range[i];
        f.side = side;
        if (side > 0 && run_start_feature >= 0 && opt.max_pair_chord_m > 0.0f) {
          const Feature& s = out[static_cast<size_t>(run_start_feature)];
          const float dx = s.x - f.x, dy = s.y - f.y, dz = s.z - f.z;
          if (dx * dx + dy * dy + dz * dz <= opt.max_pair_chord_m * opt.max_pair_chord_m)
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
