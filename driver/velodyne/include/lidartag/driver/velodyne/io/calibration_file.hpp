// Reads a Velodyne calibration file (ros-drivers YAML or VeloView XML) into a Calibration.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

#include "lidartag/driver/velodyne/calibration.hpp"
#include "lidartag/driver/velodyne/sensor_model.hpp"

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

enum class CalibrationFormat : uint8_t {
  kRosYaml,      // ros-drivers/velodyne and Autoware YAML
  kVeloViewXml,  // VeloView's and Velodyne's db.xml (a boost::serialization archive)
};

// The format of a file: XML when its first character after white space is '<', else YAML.
CalibrationFormat calibration_format(const std::string& path);

// Reads a calibration file of either format for `model`.
//
// ros-drivers YAML (angles in radians, lengths in metres): num_lasers (optional),
// distance_resolution (optional, checked to be a number), lasers: [{laser_id, rot_correction,
// vert_correction, dist_correction, vert_offset_correction, horiz_offset_correction, ...}].
// laser_id, rot_correction and vert_correction are required per laser; the offsets default to 0.
// Other keys (dist_correction_x/_y, focal_distance, focal_slope, min/max_intensity) are checked
// to be numbers when present and otherwise unused (they matter only for the HDL-64E).
//
// VeloView XML (angles in degrees, lengths in centimetres): boost_serialization > DB >
// distLSB_ (optional, checked), points_ > count (optional), item > px > id_, rotCorrection_,
// vertCorrection_ (required), distCorrection_, vertOffsetCorrection_, horizOffsetCorrection_
// (default 0), other values (distCorrectionX_/Y_, focalDistance_, focalSlope_, ...) checked to
// be numbers. Other elements of DB (colors, intensity limits, position) are not used.
//
// Both: the distance unit stays the model's own: it is fixed by the packet format, and files in
// circulation carry wrong values (velodyne.md: VLS-128 files say 0.007 where the unit is 0.004).
// Angles become degrees, lengths metres; rings are recomputed from the elevations. A file lists
// at least the model's lasers, ids 0..n-1 each once for n entries. Entries beyond the model's
// lasers (files for 32-laser sensors with 64 entries, 32 zero-filled, and num_lasers 32 or 64)
// must be all zero, intensity limits aside; otherwise the error names the first non-zero value.
// The declared count (num_lasers, points_.count) must be the model's or the listed number.
// Limits: elevations within +-90 degrees, azimuth offsets within +-180 degrees, offsets within
// +-10 m. Throws CalibrationError.
Calibration load_calibration_file(const std::string& path, Model model);

}  // namespace lidartag::velodyne
