#include "lidartag/driver/velodyne/io/calibration_file.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "calibration_entries.hpp"

namespace lidartag::velodyne {
namespace {

std::string describe(const std::string& path, const std::string& key, const std::string& problem) {
  std::string message = "calibration file '" + path + "'";
  if (!key.empty()) message += ", key '" + key + "'";
  return message + ": " + problem;
}

constexpr double kMaxOffsetM = 10.0;  // distance, vertical and horizontal offsets

std::string number_text(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

// XML when the first character that is not white space (or a UTF-8 byte order mark) is '<'.
bool looks_like_xml(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char c = 0;
  while (in.get(c)) {
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n') continue;
    if (c == '\xEF' || c == '\xBB' || c == '\xBF') continue;
    return c == '<';
  }
  return false;
}

// The rules of both formats. Entries beyond the model's lasers are accepted only all-zero: files
// for 32-laser sensors circulate with 64 entries, 32 of them zero-filled.
Calibration assemble(const detail::CalibrationEntries& file, Model model, const std::string& path) {
  const ModelSpec& spec = model_spec(model);
  const auto listed = static_cast<int>(file.lasers.size());
  const std::string model_has =
      "a " + std::string(spec.display_name) + " has " + std::to_string(spec.lasers);
  if (file.declared && *file.declared != listed && *file.declared != spec.lasers) {
    throw CalibrationError(path, file.declared_key,
                           std::to_string(*file.declared) + " declared but " +
                               std::to_string(listed) + " lasers listed");
  }
  if (listed < spec.lasers) {
    throw CalibrationError(path, file.list_key,
                           std::to_string(listed) + " lasers, but " + model_has);
  }

  Calibration calibration;
  calibration.model = model;
  calibration.distance_unit_m = spec.distance_unit_m;
  calibration.lasers.assign(static_cast<size_t>(spec.lasers), LaserCorrection{});
  std::vector<bool> seen(static_cast<size_t>(listed), false);
  for (const detail::LaserEntry& e : file.lasers) {
    if (e.id != std::floor(e.id) || std::fabs(e.id) > 1e6)
      throw CalibrationError(path, e.id_key, "not an integer");
    const int id = static_cast<int>(e.id);
    if (id < 0 || id >= listed) {
      throw CalibrationError(
          path, e.id_key,
          "laser id " + std::to_string(id) + " outside 0.." + std::to_string(listed - 1));
    }
    if (seen[static_cast<size_t>(id)]) {
      throw CalibrationError(path, e.id_key, "duplicate laser id " + std::to_string(id));
    }
    seen[static_cast<size_t>(id)] = true;
    if (id >= spec.lasers) {
      for (const detail::EntryValue& v : e.numbers) {
        if (v.value != 0.0) {
          throw CalibrationError(
              path, v.key,
              std::to_string(listed) + " lasers listed, but " + model_has + ": laser " +
                  std::to_string(id) + " is beyond the " + std::to_string(spec.lasers) +
                  " lasers, and such an entry must be all zero, found " + number_text(v.value));
        }
      }
      continue;
    }
    LaserCorrection& c = calibration.lasers[static_cast<size_t>(id)];
    c.elevation_deg = e.elevation_deg.value;
    c.azimuth_offset_deg = e.azimuth_offset_deg.value;
    c.distance_offset_m = e.distance_offset_m.value;
    c.vertical_offset_m = e.vertical_offset_m.value;
    c.horizontal_offset_m = e.horizontal_offset_m.value;
    if (std::fabs(c.elevation_deg) > 90.0) {
      throw CalibrationError(
          path, e.elevation_deg.key,
          "elevation beyond +-90 degrees (" + std::string(file.angle_unit) + " expected)");
    }
    // Finite is not enough: 1e300 turns into inf (and inf - inf = NaN) in the decoder's floats,
    // and large offsets into points kilometres away. Real files hold centimetres to a metre.
    if (std::fabs(c.azimuth_offset_deg) > 180.0) {
      throw CalibrationError(
          path, e.azimuth_offset_deg.key,
          "azimuth offset beyond +-180 degrees (" + std::string(file.angle_unit) + " expected)");
    }
    for (const detail::EntryValue* v :
         {&e.distance_offset_m, &e.vertical_offset_m, &e.horizontal_offset_m}) {
      if (std::fabs(v->value) > kMaxOffsetM) {
        throw CalibrationError(path, v->key,
                               "offset beyond +-" + std::to_string(static_cast<int>(kMaxOffsetM)) +
                                   " m (" + std::string(file.length_unit) + " expected)");
      }
    }
  }
  // `listed` entries with distinct ids in 0..listed-1: every laser of the model is present.
  calibration.update_rings();
  return calibration;
}

}  // namespace

CalibrationError::CalibrationError(const std::string& path, const std::string& key,
                                   const std::string& problem)
    : std::runtime_error(describe(path, key, problem)), path_(path), key_(key) {}

CalibrationFormat calibration_format(const std::string& path) {
  return looks_like_xml(path) ? CalibrationFormat::kVeloViewXml : CalibrationFormat::kRosYaml;
}

Calibration load_calibration_file(const std::string& path, Model model) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw CalibrationError(path, "", "no such file");
  const detail::CalibrationEntries entries =
      calibration_format(path) == CalibrationFormat::kVeloViewXml
          ? detail::parse_calibration_xml(path)
          : detail::parse_calibration_yaml(path);
  return assemble(entries, model, path);
}

}  // namespace lidartag::velodyne
