#include "lidartag/driver/velodyne/calibration.hpp"

#include <algorithm>
#include <numeric>

namespace lidartag::velodyne {

Calibration Calibration::builtin(Model model) {
  const ModelSpec& spec = model_spec(model);
  Calibration c;
  c.model = model;
  c.distance_unit_m = spec.distance_unit_m;
  c.lasers.reserve(spec.laser_table.size());
  for (const LaserSpec& l : spec.laser_table)
    c.lasers.push_back({l.elevation_deg, l.azimuth_offset_deg, l.vertical_offset_m, 0.0, 0.0});
  c.update_rings();
  return c;
}

void Calibration::update_rings() {
  std::vector<int> order(lasers.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return lasers[static_cast<size_t>(a)].elevation_deg <
           lasers[static_cast<size_t>(b)].elevation_deg;
  });
  ring_of_laser.assign(lasers.size(), 0);
  for (size_t r = 0; r < order.size(); ++r)
    ring_of_laser[static_cast<size_t>(order[r])] = static_cast<int>(r);
}

}  // namespace lidartag::velodyne
