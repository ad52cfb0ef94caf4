// What every rotation the driver hands out must satisfy, whatever bytes it was made from: shared
// by the mutation tests and the fuzz targets. Returns the first violation, or "" when none.
#pragma once

#include <cmath>
#include <sstream>
#include <string>

#include "lidartag/driver/scan.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

namespace lidartag::test {

inline std::string scan_problem(const Scan& s, velodyne::Model model) {
  std::ostringstream out;
  const velodyne::ModelSpec& spec = velodyne::model_spec(model);
  if (s.rings != spec.lasers) return "rings " + std::to_string(s.rings);
  if (s.returns != 1 && s.returns != 2) return "returns " + std::to_string(s.returns);
  if (s.columns < 0 || s.columns > s.column_capacity)
    return "columns " + std::to_string(s.columns) + " of " + std::to_string(s.column_capacity);
  const size_t cells = static_cast<size_t>(s.rings) * static_cast<size_t>(s.returns) *
                       static_cast<size_t>(s.column_capacity);
  for (size_t n : {s.x.size(), s.y.size(), s.z.size(), s.range.size(), s.azimuth_deg.size(),
                   s.time_s.size(), s.intensity.size(), s.return_type.size()})
    if (n < cells) return "cell storage smaller than rings x returns x capacity";
  if (s.laser_id.size() < static_cast<size_t>(s.rings) ||
      s.column_azimuth_deg.size() < static_cast<size_t>(s.column_capacity) ||
      s.column_time_s.size() < static_cast<size_t>(s.column_capacity))
    return "ring or column storage too small";
  for (int ring = 0; ring < s.rings; ++ring)
    if (s.laser_id[static_cast<size_t>(ring)] >= spec.lasers)
      return "ring " + std::to_string(ring) + " laser id out of range";
  // Beyond the model's range plus the largest calibration offsets, a point is corrupt.
  const float limit = static_cast<float>(spec.max_range_m) + 10.0f;
  for (int c = 0; c < s.columns; ++c) {
    const auto uc = static_cast<size_t>(c);
    if (!(s.column_azimuth_deg[uc] >= 0.0f && s.column_azimuth_deg[uc] < 360.0f)) {
      out << "column " << c << " azimuth " << s.column_azimuth_deg[uc];
      return out.str();
    }
    if (!(std::isfinite(s.column_time_s[uc]) && s.column_time_s[uc] >= 0.0)) {
      out << "column " << c << " time " << s.column_time_s[uc];
      return out.str();
    }
  }
  for (int r = 0; r < s.returns; ++r)
    for (int ring = 0; ring < s.rings; ++ring)
      for (int c = 0; c < s.columns; ++c) {
        const size_t i = s.at(r, ring, c);
        if (!(s.range[i] >= 0.0f && s.range[i] <= limit)) {
          out << "ring " << ring << " column " << c << " range " << s.range[i];
          return out.str();
        }
        if (!s.valid(i)) continue;
        if (!(std::isfinite(s.x[i]) && std::isfinite(s.y[i]) && std::isfinite(s.z[i]) &&
              std::fabs(s.x[i]) <= limit && std::fabs(s.y[i]) <= limit &&
              std::fabs(s.z[i]) <= limit)) {
          out << "ring " << ring << " column " << c << ": " << s.x[i] << " " << s.y[i] << " "
              << s.z[i];
          return out.str();
        }
        if (!(s.azimuth_deg[i] >= 0.0f && s.azimuth_deg[i] < 360.0f)) {
          out << "ring " << ring << " column " << c << " azimuth " << s.azimuth_deg[i];
          return out.str();
        }
        if (!std::isfinite(s.time_s[i])) return "non-finite point time";
        if (s.return_type[i] == ReturnType::kNone) return "valid cell without a return type";
      }
  return "";
}

}  // namespace lidartag::test
