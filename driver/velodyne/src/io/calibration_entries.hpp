// What a calibration file says, before the rules are checked: the per-laser entries of a
// ros-drivers YAML file or a VeloView XML file, in the project's units. The readers of the two
// formats (calibration_yaml.cpp, calibration_xml.cpp) only parse; calibration_file.cpp checks
// the rules once for both.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace lidartag::velodyne::detail {

// One number of an entry, with the key that names it in messages ("lasers[3].vert_correction").
struct EntryValue {
  std::string key;
  double value = 0;
};

struct LaserEntry {
  std::string where;  // the entry, e.g. "lasers[3]" or "points_[3]"
  std::string id_key;
  double id = 0;  // as written (checked to be a whole number later)
  // Converted to degrees and metres; the keys name them as the file does.
  EntryValue elevation_deg, azimuth_offset_deg, distance_offset_m, vertical_offset_m,
      horizontal_offset_m;
  // Every number of the entry except the id and the intensity limits, in file order: an entry
  // beyond the model's lasers must have all of them zero.
  std::vector<EntryValue> numbers;
};

struct CalibrationEntries {
  std::vector<LaserEntry> lasers;
  std::string list_key;                // "lasers" or "points_"
  std::optional<int> declared;         // num_lasers / the list's count, when the file states it
  std::string declared_key;            // "num_lasers" or "points_.count"
  const char* angle_unit = "radians";  // as written in the file, for messages
  const char* length_unit = "metres";
};

// Throw CalibrationError naming `path` and the key.
CalibrationEntries parse_calibration_yaml(const std::string& path);
CalibrationEntries parse_calibration_xml(const std::string& path);

}  // namespace lidartag::velodyne::detail
