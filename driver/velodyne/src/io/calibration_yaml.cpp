// ros-drivers/velodyne calibration files (YAML): angles in radians, lengths in metres.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <numbers>
#include <optional>

#include "calibration_entries.hpp"
#include "lidartag/driver/velodyne/io/calibration_file.hpp"

namespace lidartag::velodyne::detail {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// Reads `node[key]` as a finite number; empty when the key is absent.
std::optional<double> number(const YAML::Node& node, const std::string& key,
                             const std::string& where, const std::string& path) {
  const YAML::Node value = node[key];
  if (!value) return std::nullopt;
  double result = 0;
  if (!value.IsScalar() || !YAML::convert<double>::decode(value, result) ||
      !std::isfinite(result)) {
    throw CalibrationError(
        path, where + key,
        "not a number" + (value.IsScalar() ? " ('" + value.Scalar() + "')" : std::string()));
  }
  return result;
}

double required_number(const YAML::Node& node, const std::string& key, const std::string& where,
                       const std::string& path) {
  const auto value = number(node, key, where, path);
  if (!value) throw CalibrationError(path, where + key, "missing");
  return *value;
}

// Keys of an entry that are not corrections: the id, a flag, and the intensity limits (the
// zero-filled entries of 64-entry files keep min_intensity 0 and max_intensity 255).
bool is_correction_key(const std::string& key) {
  return key != "laser_id" && key != "min_intensity" && key != "max_intensity" &&
         key != "two_pt_correction_available";
}

}  // namespace

CalibrationEntries parse_calibration_yaml(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw CalibrationError(path, "", std::string("not valid YAML: ") + e.what());
  }
  if (!root.IsMap()) throw CalibrationError(path, "", "expected a mapping at the top level");
  number(root, "distance_resolution", "", path);  // validated only; see calibration_file.hpp
  CalibrationEntries entries;
  entries.list_key = "lasers";
  entries.declared_key = "num_lasers";
  const YAML::Node lasers = root["lasers"];
  if (!lasers) throw CalibrationError(path, "lasers", "missing");
  if (!lasers.IsSequence()) throw CalibrationError(path, "lasers", "expected a list of lasers");
  if (const auto declared = number(root, "num_lasers", "", path)) {
    if (*declared != std::floor(*declared) || std::fabs(*declared) > 1e6)
      throw CalibrationError(path, "num_lasers", "not an integer");
    entries.declared = static_cast<int>(*declared);
  }
  for (size_t i = 0; i < lasers.size(); ++i) {
    const YAML::Node laser = lasers[i];
    LaserEntry e;
    e.where = "lasers[" + std::to_string(i) + "]";
    const std::string prefix = e.where + ".";
    if (!laser.IsMap()) throw CalibrationError(path, e.where, "expected a mapping");
    e.id_key = prefix + "laser_id";
    e.id = required_number(laser, "laser_id", prefix, path);
    e.elevation_deg = {prefix + "vert_correction",
                       required_number(laser, "vert_correction", prefix, path) * kDegPerRad};
    e.azimuth_offset_deg = {prefix + "rot_correction",
                            required_number(laser, "rot_correction", prefix, path) * kDegPerRad};
    e.distance_offset_m = {prefix + "dist_correction",
                           number(laser, "dist_correction", prefix, path).value_or(0.0)};
    e.vertical_offset_m = {prefix + "vert_offset_correction",
                           number(laser, "vert_offset_correction", prefix, path).value_or(0.0)};
    e.horizontal_offset_m = {prefix + "horiz_offset_correction",
                             number(laser, "horiz_offset_correction", prefix, path).value_or(0.0)};
    // Used only by the HDL-64E: checked to be numbers.
    for (const char* key : {"dist_correction_x", "dist_correction_y", "focal_distance",
                            "focal_slope", "min_intensity", "max_intensity"}) {
      number(laser, key, prefix, path);
    }
    for (const auto& item : laser) {
      const std::string key = item.first.IsScalar() ? item.first.Scalar() : std::string();
      if (!is_correction_key(key)) continue;
      double value = 0;
      // Numbers only: other values (a flag) are not corrections.
      if (item.second.IsScalar() && YAML::convert<double>::decode(item.second, value))
        e.numbers.push_back({prefix + key, value});
    }
    entries.lasers.push_back(std::move(e));
  }
  return entries;
}

}  // namespace lidartag::velodyne::detail
