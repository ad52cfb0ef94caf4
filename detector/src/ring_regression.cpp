#include "lidartag/detector/ring_regression.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lidartag::detector {
namespace {

double elevation_deg(const CloudPoint& p) {
  return std::atan2(double{p.z}, std::hypot(double{p.x}, double{p.y})) * 180.0 / std::numbers::pi;
}

}  // namespace

std::vector<double> estimate_elevations(std::span<const CloudPoint> cloud, int rings) {
  std::vector<double> e;
  if (rings <= 0) return e;
  e.reserve(cloud.size());
  for (const auto& p : cloud) {
    // A NaN elevation would break the sort's ordering (and with it the sort's bounds).
    const double el = elevation_deg(p);
    if ((p.x != 0.0f || p.y != 0.0f || p.z != 0.0f) && std::isfinite(el)) e.push_back(el);
  }
  if (e.size() < static_cast<size_t>(rings)) return {};
  std::sort(e.begin(), e.end());
  // The rings - 1 widest gaps between consecutive elevations separate the beams.
  std::vector<size_t> gap(e.size() - 1);
  for (size_t i = 0; i + 1 < e.size(); ++i) gap[i] = i;
  const auto nr = static_cast<size_t>(rings);
  std::partial_sort(gap.begin(), gap.begin() + static_cast<std::ptrdiff_t>(nr - 1), gap.end(),
                    [&](size_t a, size_t b) { return e[a + 1] - e[a] > e[b + 1] - e[b]; });
  std::vector<size_t> cut(gap.begin(), gap.begin() + static_cast<std::ptrdiff_t>(nr - 1));
  std::sort(cut.begin(), cut.end());
  if (nr > 1 && e[cut.front() + 1] - e[cut.front()] <= 0.0) return {};
  std::vector<double> out;
  size_t begin = 0;
  for (size_t k = 0; k <= cut.size(); ++k) {
    const size_t end = k < cut.size() ? cut[k] + 1 : e.size();
    double sum = 0.0;
    for (size_t i = begin; i < end; ++i) sum += e[i];
    out.push_back(sum / static_cast<double>(end - begin));
    begin = end;
  }
  return out;
}

namespace {

// Columns narrower than this would make scans of millions of columns (and a NaN resolution an
// undefined conversion to int): refused.
constexpr double kMinResolutionDeg = 0.001;

bool usable_resolution(double res_deg) {
  return res_deg >= kMinResolutionDeg && res_deg <= 360.0;
}

// Sizes `out` for `rings` x 360 / resolution columns and empties it.
void prepare(int rings, double res_deg, Scan& out) {
  const int cols = static_cast<int>(std::ceil(360.0 / res_deg));
  if (out.rings != rings || out.returns != 1 || out.column_capacity != cols)
    out.reserve(rings, 1, cols);
  out.clear();
  std::fill(out.range.begin(), out.range.end(), 0.0f);
  std::fill(out.return_type.begin(), out.return_type.end(), ReturnType::kNone);
  out.columns = cols;
  for (int c = 0; c < cols; ++c) {
    out.column_azimuth_deg[static_cast<size_t>(c)] = static_cast<float>(c * res_deg);
    out.column_time_s[static_cast<size_t>(c)] = 0.0;
  }
}

// Puts `p` into its cell of `ring`; a cell hit twice keeps the nearer point. Counts in `echoes`
// (when given) a second point of the same firing as the cell's.
void place(const CloudPoint& p, double range, int ring, double res_deg, Scan& out, size_t* echoes) {
  double az = std::atan2(-double{p.y}, double{p.x}) * 180.0 / std::numbers::pi;
  if (az < 0) az += 360.0;
  // Column c is centred on azimuth c * resolution (as a sensor's firing azimuths are).
  int col = static_cast<int>(std::lround(az / res_deg));
  if (col >= out.columns) col -= out.columns;
  const size_t i = out.at(0, ring, col);
  if (out.range[i] > 0.0f) {
    if (echoes != nullptr && std::fabs(az - double{out.azimuth_deg[i]}) < kSameFiringDeg &&
        std::fabs(elevation_deg(p) - std::asin(double{out.z[i]} / double{out.range[i]}) * 180.0 /
                                         std::numbers::pi) < kSameFiringDeg)
      ++*echoes;
    if (out.range[i] <= range) return;
  }
  out.x[i] = p.x;
  out.y[i] = p.y;
  out.z[i] = p.z;
  out.range[i] = static_cast<float>(range);
  out.azimuth_deg[i] = static_cast<float>(az);
  out.time_s[i] = p.time_s;
  // NaN passes std::clamp, and converting it to an integer is undefined: it reads as 0.
  out.intensity[i] =
      static_cast<uint8_t>(p.intensity >= 0.0f ? std::min(p.intensity, 255.0f) : 0.0f);
  out.return_type[i] = ReturnType::kStrongest;
}

double range_of(const CloudPoint& p) {
  return std::sqrt(double{p.x} * p.x + double{p.y} * p.y + double{p.z} * p.z);
}

}  // namespace

bool regress_rings(std::span<const CloudPoint> cloud, const RingRegressionOptions& opt, Scan& out,
                   size_t* echoes) {
  std::vector<double> elev = opt.elevations_deg;
  if (elev.empty()) elev = estimate_elevations(cloud, opt.rings);
  const bool finite =
      std::all_of(elev.begin(), elev.end(), [](double e) { return std::isfinite(e); });
  if (elev.empty() || !finite || !usable_resolution(opt.horizontal_resolution_deg)) {
    out.clear();
    return false;
  }
  std::sort(elev.begin(), elev.end());
  const int rings = static_cast<int>(elev.size());
  prepare(rings, opt.horizontal_resolution_deg, out);
  for (const auto& p : cloud) {
    const double range = range_of(p);
    if (!(range > 0.0) || !std::isfinite(range)) continue;
    const double e = elevation_deg(p);
    // Nearest beam elevation.
    const auto it = std::lower_bound(elev.begin(), elev.end(), e);
    int ring = static_cast<int>(it - elev.begin());
    if (ring == rings ||
        (ring > 0 && e - elev[static_cast<size_t>(ring - 1)] < elev[static_cast<size_t>(ring)] - e))
      --ring;
    place(p, range, ring, opt.horizontal_resolution_deg, out, echoes);
  }
  return true;
}

bool organise_rings(std::span<const CloudPoint> cloud, int rings, double horizontal_resolution_deg,
                    Scan& out, size_t* echoes) {
  if (rings <= 0 || !usable_resolution(horizontal_resolution_deg)) {
    out.clear();
    return false;
  }
  prepare(rings, horizontal_resolution_deg, out);
  for (const auto& p : cloud) {
    const double range = range_of(p);
    if (!(range > 0.0) || !std::isfinite(range) || p.ring < 0 || p.ring >= rings) continue;
    place(p, range, p.ring, horizontal_resolution_deg, out, echoes);
  }
  return true;
}

}  // namespace lidartag::detector
