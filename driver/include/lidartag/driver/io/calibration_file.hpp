// Reads a ros-drivers/velodyne calibration file (YAML) into a Calibration.
#pragma once

#include <stdexcept>
#include <string>

#include "lidartag/driver/calibration.hpp"
#include "lidartag/driver/sensor_model.hpp"

namespace lidartag::velodyne {

// A calibration file cannot be used; what() names the file and, where one is at fault, the key
// (e.g. "lasers[3].vert_correction").
class CalibrationError : public std::runtime_error {
 public:
  CalibrationError(const std::string& path, const std::string& key, const std::string& problem);
  const std::string& path() const { return path_; }
  const std::string& key() const { return key_; }

 private:
  std::string path_, key_;
};

// Keys read (ros-drivers convention, angles in radians, lengths in metres):
//   num_lasers (optional; must equal the number of entries), distance_resolution (optional,
//   checked to be a number), lasers: [{laser_id, rot_correction, vert_correction,
//   dist_correction, vert_offset_correction, horiz_offset_correction, ...}].
// laser_id, rot_correction and vert_correction are required per laser; the offsets default to 0.
// Other keys (dist_correction_x/_y, focal_distance, focal_slope, min/max_intensity) are checked
// to be numbers when present and otherwise unused (they matter only for the HDL-64E).
// The distance unit stays the model's own: it is fixed by the packet format, and files in
// circulation carry wrong values (velodyne.md: VLS-128 files say 0.007 where the unit is 0.004).
// Angles become degrees; rings are recomputed from the elevations. Laser ids must be exactly
// 0..n-1 with n the model's laser count. Limits: elevations within +-90 degrees, azimuth offsets
// within +-180 degrees, offsets within +-10 m. Throws CalibrationError.
Calibration load_calibration_file(const std::string& path, Model model);

}  // namespace lidartag::velodyne
