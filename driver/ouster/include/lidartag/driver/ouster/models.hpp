// Nominal Ouster sensors (the simulator's, and model names such as `os1-128`): per model its beam
// table as data, turned into the SensorInfo a sensor of that model would report for a lidar mode
// and profile. The OS1 tables are representative of the product line (evenly spaced beams); the
// OS0 and OS2 tables are those real units of firmware 2.x reported (docs/ouster.md, "Simulated
// sensors"). Neither is any other unit's factory calibration: a real sensor's metadata wins.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lidartag/driver/ouster/metadata.hpp"

namespace lidartag::driver::ouster {

enum class Model : uint8_t { kOs1_64, kOs1_128, kOs0_32, kOs0_128, kOs2_32, kOs2_128 };

struct ModelSpec {
  Model model;
  std::string_view name;       // "os1-64"
  std::string_view prod_line;  // "OS-1-64"
  int beams;
  // Beam altitudes: `beams` angles evenly spaced from the top to the bottom, degrees (when
  // `altitude_table_deg` is empty).
  double altitude_top_deg;
  double altitude_bottom_deg;
  // Beam azimuth offsets (+ clockwise, the metadata's sign), repeating every 4 beams, degrees
  // (when `azimuth_table_deg` is empty).
  std::array<double, 4> azimuth_pattern_deg;
  // A unit's own tables (`beams` angles each, the first beam the top one, degrees, the metadata's
  // beam_altitude_angles and beam_azimuth_angles); empty: the evenly spaced beams above.
  std::span<const double> altitude_table_deg;
  std::span<const double> azimuth_table_deg;
  double lidar_origin_to_beam_origin_mm;
  // lidar_to_sensor_transform's translation along z (the rotation is 180 deg about z), mm.
  double lidar_to_sensor_z_mm;
  double min_range_m;  // closer returns are not reported
  double max_range_m;  // farthest reported return (80 % reflective target)
};

const ModelSpec& model_spec(Model m);
std::optional<Model> model_from_name(std::string_view name);
std::string model_names();  // "os1-64, os1-128, os0-32, ..."

// The model name of the sensor `info` describes, as configurations name it: "os" + the product
// line's number + "-" + its beams ("OS-1-128" -> "os1-128", "OS-0-32-U1" -> "os0-32"); "os-" +
// the beams when the product line names no number (an older or edited file).
std::string model_name(const SensorInfo& info);
// Whether `name` is such a model name: os0, os1, os2 or os (any line) with 16, 32, 64 or 128
// beams, lower case ("os1-128").
bool is_model_name(std::string_view name);
// Whether `info` describes a sensor of model `name` (model_name(info) == name; only the beams
// when either names no product line, "os-128").
bool describes_model(const SensorInfo& info, std::string_view name);

// The beam altitudes a sensor of model `m` reports (the first beam the top one), degrees: its
// table, or its evenly spaced beams rounded to 1e-4 degree as sensors report them. Any lidar mode.
std::vector<double> nominal_beam_altitudes_deg(Model m);

// The SensorInfo (nested layout) a sensor of model `m` reports in lidar mode `columns` x
// `rate_hz` with `profile`: the model's beam table, pixel_shift_by_row = each beam's azimuth
// offset in columns (rounded), 16 columns a packet, the whole rotation, lidar_to_sensor_transform
// 180 deg about z and the model's height (36.18 mm for OS0 and OS1, Ouster's documented default).
// Throws std::invalid_argument for a
// lidar mode the sensors lack (columns 512/1024/2048, rate 10/20; 2048 only at 10).
SensorInfo nominal_sensor_info(Model m, int columns, int rate_hz, Profile profile);

}  // namespace lidartag::driver::ouster
