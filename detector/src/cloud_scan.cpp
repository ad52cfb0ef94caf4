#include "lidartag/detector/cloud_scan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

#include "lidartag/detector/ring_regression.hpp"

namespace lidartag::detector {
namespace {

// Rings of a ring field (the largest spinning sensors have 128).
constexpr int kMaxRings = 256;

bool is_float(double v) {
  return std::fabs(v) <= std::numeric_limits<float>::max();
}

double at_or(std::span<const double> field, size_t k, double fallback) {
  return field.empty() ? fallback : field[k];
}

double azimuth_of(double x, double y) {
  double az = std::atan2(-y, x) * 180.0 / std::numbers::pi;
  return az < 0 ? az + 360.0 : az;
}

// A ring number, or -1 when it is not a whole number in [0, limit).
int ring_of(double r, int limit) {
  if (!(r >= 0 && r < limit) || r != std::floor(r)) return -1;
  return static_cast<int>(r);
}

uint8_t intensity_of(double v, double scale) {
  const double s = v * scale;
  // NaN fails the comparison and reads as 0 (converting it to an integer is undefined).
  return static_cast<uint8_t>(s >= 0.0 ? std::min(s, 255.0) : 0.0);
}

ReturnType return_type_of(double v) {
  return v >= 1 && v <= 4 && v == std::floor(v) ? static_cast<ReturnType>(static_cast<int>(v))
                                                : ReturnType::kStrongest;
}

// Columns without any azimuth (or time) take their neighbour's.
template <typename T>
void fill_gaps(std::vector<T>& values, const std::vector<bool>& known, int columns) {
  int last = -1;
  for (int c = 0; c < columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    if (known[uc]) {
      if (last < 0)
        for (int b = 0; b < c; ++b) values[static_cast<size_t>(b)] = values[uc];
      last = c;
    } else if (last >= 0) {
      values[uc] = values[static_cast<size_t>(last)];
    }
  }
}

// Organised with ring numbers: point k is row k / width, column k % width; rows are the rings of
// return 0, then those of return 1.
void to_grid(const CloudFields& f, int rings, int returns, double scale, CloudScanReport& report,
             Scan& out) {
  const int columns = static_cast<int>(f.width);
  if (out.rings != rings || out.returns != returns || out.column_capacity != columns)
    out.reserve(rings, returns, columns);
  out.clear();
  std::fill(out.range.begin(), out.range.end(), 0.0f);
  std::fill(out.return_type.begin(), out.return_type.end(), ReturnType::kNone);
  std::fill(out.azimuth_deg.begin(), out.azimuth_deg.end(), 0.0f);
  std::fill(out.time_s.begin(), out.time_s.end(), 0.0f);
  out.columns = columns;
  std::vector<bool> az_known(f.width, false), time_known(f.width, false);
  for (size_t k = 0; k < f.x.size(); ++k) {
    const auto row = static_cast<int>(k / f.width);
    const auto col = static_cast<int>(k % f.width);
    const auto ucol = static_cast<size_t>(col);
    const int ring = ring_of(f.ring[k], rings);
    const bool no_return = std::isnan(f.x[k]) || std::isnan(f.y[k]) || std::isnan(f.z[k]);
    const bool coordinates = is_float(f.x[k]) && is_float(f.y[k]) && is_float(f.z[k]);
    if (!no_return && !coordinates) ++report.skipped_coordinates;
    if (ring < 0) {
      if (!no_return && coordinates) ++report.skipped_rings;
      continue;
    }
    const size_t i = out.at(row / rings, ring, col);
    const double az = at_or(f.azimuth_deg, k,
                            no_return || !coordinates ? std::numeric_limits<double>::quiet_NaN()
                                                      : azimuth_of(f.x[k], f.y[k]));
    const double t = at_or(f.time_s, k, std::numeric_limits<double>::quiet_NaN());
    if (std::isfinite(az) && std::fabs(az) <= 720.0) {
      out.azimuth_deg[i] = static_cast<float>(az);
      // The first row that has one gives the column's azimuth (one ring for every column of a
      // dump, so that the steps between columns are the sensor's).
      if (!az_known[ucol]) out.column_azimuth_deg[ucol] = static_cast<float>(az);
      az_known[ucol] = true;
    }
    if (std::isfinite(t) && is_float(t)) {
      out.time_s[i] = static_cast<float>(t);
      if (!time_known[ucol]) out.column_time_s[ucol] = t;
      time_known[ucol] = true;
    }
    if (no_return || !coordinates) continue;
    const double range = std::sqrt(f.x[k] * f.x[k] + f.y[k] * f.y[k] + f.z[k] * f.z[k]);
    if (!(range > 0.0) || !is_float(range)) continue;
    if (out.range[i] > 0.0f && out.range[i] <= range) continue;  // the nearer of two
    out.x[i] = static_cast<float>(f.x[k]);
    out.y[i] = static_cast<float>(f.y[k]);
    out.z[i] = static_cast<float>(f.z[k]);
    out.range[i] = static_cast<float>(range);
    out.intensity[i] = intensity_of(f.intensity[k], scale);
    out.return_type[i] = return_type_of(at_or(f.return_type, k, 1));
  }
  fill_gaps(out.column_azimuth_deg, az_known, columns);
  fill_gaps(out.column_time_s, time_known, columns);
}

// The column width for a cloud of level rings (CloudScanOptions::resolution_deg 0): a share of the
// median azimuth step between neighbouring points of one ring (steps within kSameFiringDeg, two
// echoes of one firing, left out), a little under the sensor's step so that the jitter of its
// firing azimuths does not put two firings into one column; 0 when fewer than kMinColumnSteps
// steps are seen.
double column_width_of(std::span<const CloudPoint> cloud, int rings) {
  std::vector<std::pair<int, float>> az;  // ring, azimuth in degrees
  az.reserve(cloud.size());
  for (const auto& p : cloud)
    if (p.ring >= 0 && p.ring < rings && (p.x != 0.0f || p.y != 0.0f))
      az.emplace_back(p.ring, static_cast<float>(azimuth_of(p.x, p.y)));
  std::sort(az.begin(), az.end());
  std::vector<float> steps;
  steps.reserve(az.size());
  for (size_t k = 0; k + 1 < az.size(); ++k) {
    const float step = az[k + 1].second - az[k].second;
    if (az[k + 1].first == az[k].first && step > kSameFiringDeg) steps.push_back(step);
  }
  if (steps.size() < kMinColumnSteps) return 0.0;
  const auto mid = steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2);
  std::nth_element(steps.begin(), mid, steps.end());
  return std::clamp(kColumnStepShare * double{*mid}, kMinColumnWidthDeg, kMaxColumnWidthDeg);
}

// Whether the points of each ring lie on one cone: their mean distance from their ring's mean
// elevation is within kMaxRingSpreadDeg. Judged on the points at kLevelMinRangeM or farther when
// there are kLevelMinPoints of them: a beam's origin sits centimetres off the sensor's axis, which
// moves the elevation of a point 1 m away, seen from the cloud's origin, by a degree or more (a
// RoboSense Bpearl's rings, read 0.2 to 13 m away, spread 1.9 degrees over all points, 0.08
// beyond 3 m).
bool rings_level(const CloudFields& f, int rings) {
  size_t far = 0;
  for (size_t k = 0; k < f.x.size(); ++k)
    if (f.x[k] * f.x[k] + f.y[k] * f.y[k] + f.z[k] * f.z[k] >= kLevelMinRangeM * kLevelMinRangeM)
      ++far;
  const double min_range2 = far >= kLevelMinPoints ? kLevelMinRangeM * kLevelMinRangeM : 0.0;
  std::vector<double> sum(static_cast<size_t>(rings), 0.0);
  std::vector<size_t> count(static_cast<size_t>(rings), 0);
  std::vector<std::pair<int, float>> elevations;  // ring, degrees: each point's, computed once
  elevations.reserve(f.x.size());
  for (size_t k = 0; k < f.x.size(); ++k) {
    const int ring = ring_of(f.ring[k], rings);
    const double h = std::hypot(f.x[k], f.y[k]);
    if (ring < 0 || !(h > 0.0 || f.z[k] != 0.0)) continue;  // no ring, no return
    if (h * h + f.z[k] * f.z[k] < min_range2) continue;
    const double e = std::atan2(f.z[k], h) * 180.0 / std::numbers::pi;
    if (!std::isfinite(e)) continue;
    elevations.emplace_back(ring, static_cast<float>(e));
    sum[static_cast<size_t>(ring)] += e;
    ++count[static_cast<size_t>(ring)];
  }
  double spread = 0.0;
  for (const auto& [ring, e] : elevations) {
    const auto r = static_cast<size_t>(ring);
    spread += std::fabs(e - sum[r] / static_cast<double>(count[r]));
  }
  return elevations.empty() || spread / static_cast<double>(elevations.size()) <= kMaxRingSpreadDeg;
}

}  // namespace

CloudFields cloud_fields_by_name(const std::vector<std::string>& names,
                                 const std::vector<std::span<const double>>& columns, size_t width,
                                 size_t height) {
  CloudFields fields;
  std::span<const double>* const targets[] = {
      &fields.x,    &fields.y,           &fields.z,      &fields.intensity,
      &fields.ring, &fields.azimuth_deg, &fields.time_s, &fields.return_type};
  static_assert(std::size(targets) == kCloudFieldNames.size());
  for (size_t k = 0; k < kCloudFieldNames.size(); ++k) {
    const auto it = std::find(names.begin(), names.end(), kCloudFieldNames[k]);  // the first
    if (it != names.end()) *targets[k] = columns[static_cast<size_t>(it - names.begin())];
  }
  fields.width = width;
  fields.height = height;
  return fields;
}

CloudFields cloud_fields_by_name(const std::vector<std::string>& names,
                                 const std::vector<std::vector<double>>& columns, size_t width,
                                 size_t height) {
  return cloud_fields_by_name(
      names, std::vector<std::span<const double>>(columns.begin(), columns.end()), width, height);
}

CloudScanOptions cloud_scan_options(const CloudFields& cloud,
                                    std::vector<double> model_elevations_deg, int rings,
                                    double resolution_deg) {
  CloudScanOptions options;
  options.resolution_deg = resolution_deg;
  if (!model_elevations_deg.empty()) {
    options.rings = static_cast<int>(model_elevations_deg.size());
    options.elevations_deg = std::move(model_elevations_deg);
  } else if (cloud.ring.empty()) {
    options.rings = rings;
  } else {
    options.unlevel_ring_beams = rings;
  }
  return options;
}

CloudScanReport cloud_to_scan(const CloudFields& f, const CloudScanOptions& options, Scan& out) {
  CloudScanReport report;
  const size_t n = f.x.size();
  if (f.intensity.empty() && n > 0) {
    throw CloudError(
        "no intensity field: the detector reads a tag's code from intensity, so a cloud of "
        "x, y, z alone gives no tags (write the intensity too, e.g. PCL's PointXYZI)");
  }
  for (const auto* field :
       {&f.y, &f.z, &f.intensity, &f.ring, &f.azimuth_deg, &f.time_s, &f.return_type}) {
    if (!field->empty() && field->size() != n) throw CloudError("fields of different sizes");
  }
  if (f.height > 1 && f.width * f.height != n)
    throw CloudError("width x height is not the number of points");

  // Intensities of 0..1 (some tools normalise them) would all read as 0 or 1 of 255.
  double max_intensity = 0.0;
  for (size_t k = 0; k < n; ++k)
    if (std::isfinite(f.intensity[k]) && !std::isnan(f.x[k]))
      max_intensity = std::max(max_intensity, f.intensity[k]);
  report.intensity_scaled = max_intensity > 0.0 && max_intensity <= 1.0;
  const double scale = report.intensity_scaled ? 255.0 : 1.0;

  int rings = options.rings;
  if (!f.ring.empty() && rings <= 0) {
    int max_ring = -1;
    for (size_t k = 0; k < n; ++k) max_ring = std::max(max_ring, ring_of(f.ring[k], kMaxRings));
    rings = max_ring + 1;
    if (rings <= 0)
      throw CloudError("no point has a ring number in 0.." + std::to_string(kMaxRings - 1));
  }
  if (!f.ring.empty() && !rings_level(f, rings)) {
    report.rings_not_level = true;
    if (!options.elevations_deg.empty() || options.unlevel_ring_beams > 0) {
      CloudFields without = f;
      without.ring = {};
      CloudScanOptions regress = options;
      if (options.elevations_deg.empty()) regress.rings = options.unlevel_ring_beams;
      CloudScanReport r = cloud_to_scan(without, regress, out);
      r.rings_not_level = true;
      return r;
    }
  }
  if (!f.ring.empty() && f.height > 1 && f.width > 0 &&
      f.height % static_cast<size_t>(rings) == 0 && f.height / static_cast<size_t>(rings) <= 2) {
    report.grid = true;
    to_grid(f, rings, static_cast<int>(f.height / static_cast<size_t>(rings)), scale, report, out);
    report.points = out.point_count();
    return report;
  }

  // Unorganised (or rows that are not rings): columns by azimuth.
  std::vector<CloudPoint> cloud;
  cloud.reserve(n);
  for (size_t k = 0; k < n; ++k) {
    if (std::isnan(f.x[k]) || std::isnan(f.y[k]) || std::isnan(f.z[k])) continue;  // no return
    if (!is_float(f.x[k]) || !is_float(f.y[k]) || !is_float(f.z[k])) {
      ++report.skipped_coordinates;
      continue;
    }
    CloudPoint p;
    p.x = static_cast<float>(f.x[k]);
    p.y = static_cast<float>(f.y[k]);
    p.z = static_cast<float>(f.z[k]);
    p.intensity = static_cast<float>(intensity_of(f.intensity[k], scale));
    const double t = at_or(f.time_s, k, 0.0);
    p.time_s = std::isfinite(t) && is_float(t) ? static_cast<float>(t) : 0.0f;
    if (!f.ring.empty()) {
      p.ring = ring_of(f.ring[k], rings);
      if (p.ring < 0) {
        ++report.skipped_rings;
        continue;
      }
    }
    cloud.push_back(p);
  }
  // Points a cell can take (a return: a finite range above 0), against those in the scan after.
  const auto placeable =
      static_cast<size_t>(std::count_if(cloud.begin(), cloud.end(), [&](const CloudPoint& p) {
        const double r2 = double{p.x} * p.x + double{p.y} * p.y + double{p.z} * p.z;
        return r2 > 0.0 && std::isfinite(r2) && (f.ring.empty() || p.ring < rings);
      }));
  if (!(options.resolution_deg >= 0.0))
    throw CloudError("a column width of " + std::to_string(options.resolution_deg) +
                     " degrees (0: the cloud's own)");
  const double own = options.resolution_deg > 0.0 || f.ring.empty() || report.rings_not_level
                         ? 0.0
                         : column_width_of(cloud, rings);
  report.column_from_cloud = own > 0.0;
  report.resolution_deg = options.resolution_deg > 0.0 ? options.resolution_deg
                          : report.column_from_cloud   ? own
                                                       : kDefaultColumnWidthDeg;
  if (!f.ring.empty()) {
    if (!organise_rings(cloud, rings, report.resolution_deg, out, &report.echoes))
      throw CloudError("cannot organise the rings (column width " +
                       std::to_string(report.resolution_deg) + " degrees)");
    report.points = out.point_count();
    report.merged = placeable > report.points ? placeable - report.points : 0;
    return report;
  }
  report.regressed = true;
  RingRegressionOptions ro;
  ro.horizontal_resolution_deg = report.resolution_deg;
  ro.elevations_deg = options.elevations_deg;
  ro.rings = options.rings;
  if (ro.elevations_deg.empty() && ro.rings <= 0) {
    throw NoRingFieldError(
        "no ring field: give the sensor model (its beam elevations) or the number of rings to "
        "regress");
  }
  if (!regress_rings(cloud, ro, out, &report.echoes)) {
    throw CloudError("cannot regress rings (fewer than " +
                     std::to_string(ro.elevations_deg.empty()
                                        ? ro.rings
                                        : static_cast<int>(ro.elevations_deg.size())) +
                     " distinct elevations)");
  }
  report.points = out.point_count();
  report.merged = placeable > report.points ? placeable - report.points : 0;
  return report;
}

}  // namespace lidartag::detector
