#include "lidartag/driver/io/calibration_file.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <utility>
#include <vector>

namespace lidartag::velodyne {
namespace {

std::string describe(const std::string& path, const std::string& key, const std::string& problem) {
  std::string message = "calibration file '" + path + "'";
  if (!key.empty()) message += ", key '" + key + "'";
  return message + ": " + problem;
}

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

int integer(const YAML::Node& node, const std::string& key, const std::string& where,
            const std::string& path) {
  const double value = required_number(node, key, where, path);
  if (value != std::floor(value) || std::fabs(value) > 1e6) {
    throw CalibrationError(path, where + key, "not an integer");
  }
  return static_cast<int>(value);
}

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr double kMaxOffsetM = 10.0;  // distance, vertical and horizontal offsets

}  // namespace

CalibrationError::CalibrationError(const std::string& path, const std::string& key,
                                   const std::string& problem)
    : std::runtime_error(describe(path, key, problem)), path_(path), key_(key) {}

Calibration load_calibration_file(const std::string& path, Model model) {
  const ModelSpec& spec = model_spec(model);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw CalibrationError(path, "", "no such file");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw CalibrationError(path, "", std::string("not valid YAML: ") + e.what());
  }
  if (!root.IsMap()) throw CalibrationError(path, "", "expected a mapping at the top level");
  number(root, "distance_resolution", "", path);  // validated only; see the header
  const YAML::Node lasers = root["lasers"];
  if (!lasers) throw CalibrationError(path, "lasers", "missing");
  if (!lasers.IsSequence()) throw CalibrationError(path, "lasers", "expected a list of lasers");
  if (root["num_lasers"]) {
    const int declared = integer(root, "num_lasers", "", path);
    if (declared != static_cast<int>(lasers.size())) {
      throw CalibrationError(path, "num_lasers",
                             std::to_string(declared) + " declared but " +
                                 std::to_string(lasers.size()) + " lasers listed");
    }
  }
  if (static_cast<int>(lasers.size()) != spec.lasers) {
    throw CalibrationError(path, "lasers",
                           std::to_string(lasers.size()) + " lasers, but a " +
                               std::string(spec.display_name) + " has " +
                               std::to_string(spec.lasers));
  }

  Calibration calibration;
  calibration.model = model;
  calibration.distance_unit_m = spec.distance_unit_m;
  calibration.lasers.assign(static_cast<size_t>(spec.lasers), LaserCorrection{});
  std::vector<bool> seen(static_cast<size_t>(spec.lasers), false);
  for (size_t i = 0; i < lasers.size(); ++i) {
    const YAML::Node laser = lasers[i];
    const std::string where = "lasers[" + std::to_string(i) + "].";
    if (!laser.IsMap())
      throw CalibrationError(path, "lasers[" + std::to_string(i) + "]", "expected a mapping");
    const int id = integer(laser, "laser_id", where, path);
    if (id < 0 || id >= spec.lasers) {
      throw CalibrationError(
          path, where + "laser_id",
          "laser id " + std::to_string(id) + " outside 0.." + std::to_string(spec.lasers - 1));
    }
    if (seen[static_cast<size_t>(id)]) {
      throw CalibrationError(path, where + "laser_id", "duplicate laser id " + std::to_string(id));
    }
    seen[static_cast<size_t>(id)] = true;
    LaserCorrection& c = calibration.lasers[static_cast<size_t>(id)];
    c.elevation_deg = required_number(laser, "vert_correction", where, path) * kDegPerRad;
    c.azimuth_offset_deg = required_number(laser, "rot_correction", where, path) * kDegPerRad;
    c.distance_offset_m = number(laser, "dist_correction", where, path).value_or(0.0);
    c.vertical_offset_m = number(laser, "vert_offset_correction", where, path).value_or(0.0);
    c.horizontal_offset_m = number(laser, "horiz_offset_correction", where, path).value_or(0.0);
    for (const char* key : {"dist_correction_x", "dist_correction_y", "focal_distance",
                            "focal_slope", "min_intensity", "max_intensity"}) {
      number(laser, key, where, path);
    }
    if (std::fabs(c.elevation_deg) > 90.0) {
      throw CalibrationError(path, where + "vert_correction",
                             "elevation beyond +-90 degrees (radians expected)");
    }
    // Finite is not enough: 1e300 turns into inf (and inf - inf = NaN) in the decoder's floats,
    // and large offsets into points kilometres away. Real files hold centimetres to a metre.
    if (std::fabs(c.azimuth_offset_deg) > 180.0) {
      throw CalibrationError(path, where + "rot_correction",
                             "azimuth offset beyond +-180 degrees (radians expected)");
    }
    const std::pair<const char*, double> offsets[] = {
        {"dist_correction", c.distance_offset_m},
        {"vert_offset_correction", c.vertical_offset_m},
        {"horiz_offset_correction", c.horizontal_offset_m}};
    for (const auto& [key, value] : offsets) {
      if (std::fabs(value) > kMaxOffsetM) {
        throw CalibrationError(path, where + key,
                               "offset beyond +-" + std::to_string(static_cast<int>(kMaxOffsetM)) +
                                   " m (metres expected)");
      }
    }
  }
  // n entries with distinct ids in 0..n-1: every laser is present.
  calibration.update_rings();
  return calibration;
}

}  // namespace lidartag::velodyne
